#!/usr/bin/env python3
"""The robot scene end to end with the real tools: flsm_node reads urdf/gripper.urdf through
~robot_description, the real robot_state_publisher turns the joint states this test publishes
into the links' tf frames, and the gripper's pads close on the bunny resting on the ground and
lift it 10 cm.

Checked: the object rises at least MIN_LIFT; over HOLD seconds of holding it moves less than
MAX_SLIP relative to the palm (tf: flsm_object against the palm link); the fingers' vertical
contact forces (~contact_wrenches entries robot/finger_left and robot/finger_right, in the link
frames, turned into the world with tf) carry its weight, the lattice's mass (~state mass) times
g, within WEIGHT_TOLERANCE, all of this over a hold in the middle of which the joint states pause
for PAUSE seconds (so does robot_state_publisher's tf): the pause changes nothing the object
does. No frame miss is counted by the time the robot's colliders have all joined (their
frames appear after the node started listening: they are waited for, not missed). Later misses
are logged, not asserted: on a loaded machine a publisher (the joint state player,
robot_state_publisher) may stall for more than the 0.5 s stale time (test_collider_follower
checks the rule on a clock it sets).
"""

import json
import os
import subprocess
import sys
import threading
import time
import unittest

import numpy as np
import rospy
import rostest
import tf2_ros

from deformable_flsm.msg import ContactWrenches
from flsm_testing import FlsmClient

PKG = 'deformable_flsm'
GRAVITY = 9.81
JOINTS = ('lift', 'finger_left_joint', 'finger_right_joint')
FINGERS = ('finger_left', 'finger_right')
# urdf/gripper.urdf: the pads' centres are this far above the world origin at lift 0 (m).
PAD_BELOW_LIFT = 0.10
# Parked: up above the object, wide open (m).
UP, WIDE = 0.08, 0.15
# The pads wait this far from the object's contact surface before closing (m), and press this
# far into it (m); then they lift it LIFT (m).
CLEARANCE, SQUEEZE, LIFT = 0.04, 0.035, 0.10
# Seconds: open around the object, come down, close, let the grip settle, lift, let the lifted
# object stop swinging; then HOLD seconds of holding are measured, with a PAUSE of the joint
# states (and so of tf) starting PAUSE_AT seconds into the hold.
AROUND, DOWN, CLOSE, GRIP, RAISE, SWING, HOLD = 2.0, 2.0, 2.0, 1.0, 2.0, 1.5, 5.0
PAUSE_AT, PAUSE = 2.0, 0.4
# What the issue asks of a grasp: risen >= 8 cm, slipped < 5 mm over the hold, the fingers'
# vertical forces the weight within 5 %.
MIN_LIFT, MAX_SLIP, WEIGHT_TOLERANCE = 0.08, 0.005, 0.05
# Settled enough to aim at: no particle faster than this (m/s).
SETTLED = 0.005


class Joints(object):
    """The joints' waypoints [(t, q)], each q held after its time and approached smoothly before,
    and pauses [(t0, t1)] without joint states, played by joint_states_player.py (a process of
    its own, see there) at 100 Hz."""

    def __init__(self, q):
        self.lock = threading.Lock()
        self.waypoints = [(0.0, [float(v) for v in q])]
        self.pauses = []
        player = os.path.join(os.path.dirname(os.path.abspath(__file__)), 'joint_states_player.py')
        self.proc = subprocess.Popen([sys.executable, player], stdin=subprocess.PIPE)
        self.send()

    def send(self):
        with self.lock:
            line = json.dumps({'names': list(JOINTS), 'waypoints': self.waypoints,
                               'pauses': self.pauses})
        self.proc.stdin.write((line + '\n').encode())
        self.proc.stdin.flush()

    def go(self, duration, lift=None, left=None, right=None):
        """Moves to the joint values given over `duration` s from the end of the last move (or
        now); returns the time it gets there."""
        with self.lock:
            t0 = max(rospy.get_time(), self.waypoints[-1][0])
            q = list(self.waypoints[-1][1])
            for k, v in enumerate((lift, left, right)):
                if v is not None:
                    q[k] = float(v)
            self.waypoints.append((t0 + duration, q))
        self.send()
        return t0 + duration

    def pause(self, t0, t1):
        with self.lock:
            self.pauses.append((t0, t1))
        self.send()

    def stop(self):
        self.proc.stdin.close()
        self.proc.wait(timeout=10.0)


def vector(v):
    return np.array([v.x, v.y, v.z])


def rotate(q, v):
    """v rotated by the unit quaternion q (geometry_msgs Quaternion)."""
    u = np.array([q.x, q.y, q.z])
    return v + 2.0 * np.cross(u, np.cross(u, v) + q.w * v)


class RobotGraspTest(unittest.TestCase):

    @classmethod
    def setUpClass(cls):
        rospy.init_node('test_robot_grasp')
        cls.joints = Joints((UP, WIDE, WIDE))
        cls.flsm = FlsmClient()
        cls.tf_buffer = tf2_ros.Buffer()
        cls.tf_listener = tf2_ros.TransformListener(cls.tf_buffer)
        cls.samples = []
        cls.frames = set()
        cls.lock = threading.Lock()
        rospy.Subscriber('/flsm_node/contact_wrenches', ContactWrenches, cls.on_wrenches,
                         queue_size=50)

    @classmethod
    def tearDownClass(cls):
        cls.joints.stop()

    @classmethod
    def on_wrenches(cls, msg):
        """Per message: the fingers' summed vertical force in the world, the object's position
        in the world and relative to the palm, the fingers' contact counts."""
        by_id = dict(zip(msg.ids, zip(msg.wrenches, msg.contacts)))
        ids = ['robot/' + f for f in FINGERS]
        if not all(i in by_id for i in ids):
            return
        try:
            obj = cls.tf_buffer.lookup_transform('world', 'flsm_object', rospy.Time(0))
            palm = cls.tf_buffer.lookup_transform('world', 'palm', rospy.Time(0))
            fz = 0.0
            for i in ids:
                w, _ = by_id[i]
                cls.frames.add((i, w.header.frame_id))
                link = cls.tf_buffer.lookup_transform('world', w.header.frame_id, rospy.Time(0))
                fz += rotate(link.transform.rotation, vector(w.wrench.force))[2]
        except tf2_ros.TransformException:
            return
        p = vector(obj.transform.translation)
        with cls.lock:
            cls.samples.append((msg.header.stamp.to_sec(), fz, p,
                                p - vector(palm.transform.translation),
                                [by_id[i][1] for i in ids]))

    def between(self, t0, t1):
        with self.lock:
            return [s for s in self.samples if t0 <= s[0] <= t1]

    def test_gripper_lifts_and_holds_the_bunny(self):
        f = self.flsm
        # The ground and the gripper's 6 collision elements.
        joined = f.wait_state(lambda s: s.colliders == 7, 30.0)
        self.assertIsNotNone(joined, 'the robot\'s colliders did not all join')
        self.assertEqual(joined.collider_frame_misses, 0,
                         'frames not seen yet were counted as missed')
        s = f.wait_state(lambda s: s.sim_time > 2.0 and s.max_speed < SETTLED, 90.0)
        self.assertIsNotNone(s, 'the bunny did not come to rest on the ground')
        weight = s.mass * GRAVITY
        x = f.particles()
        com = x.mean(axis=0)
        band = x[(np.abs(x[:, 2] - com[2]) < 0.02) & (np.abs(x[:, 0]) < 0.04)]
        self.assertGreater(len(band), 3)
        steps = np.linalg.norm(np.diff(x, axis=0), axis=1)
        surface = 0.5 * float(np.min(steps[steps > 1e-6]))  # ~contact_radius 0: half a cell
        lo, hi = band[:, 1].min() - surface, band[:, 1].max() + surface
        grip = com[2] - PAD_BELOW_LIFT
        rest = vector(self.tf_buffer.lookup_transform('world', 'flsm_object', rospy.Time(0),
                                                      rospy.Duration(5.0)).transform.translation)
        rospy.loginfo('robot grasp: weight %.3f N, object %.3f m across y at z %.3f',
                      weight, hi - lo, com[2])
        j = self.joints
        j.go(AROUND, left=-lo + CLEARANCE, right=hi + CLEARANCE)
        j.go(DOWN, lift=grip)
        j.go(CLOSE, left=-lo - SQUEEZE, right=hi - SQUEEZE)
        gripped = j.go(GRIP)
        lifted = j.go(RAISE, lift=grip + LIFT)
        t0 = lifted + SWING
        t1 = t0 + HOLD
        j.pause(t0 + PAUSE_AT, t0 + PAUSE_AT + PAUSE)
        while rospy.get_time() < t0 and not rospy.is_shutdown():
            time.sleep(0.05)
        misses_before = f.state().collider_frame_misses
        while rospy.get_time() < t1 + 0.3 and not rospy.is_shutdown():
            time.sleep(0.1)
        grip_samples = self.between(gripped - 0.3, gripped)
        hold = self.between(t0, t1)
        self.assertGreater(len(grip_samples), 3)
        self.assertGreater(len(hold), 0.5 * HOLD * 30.0 / 2)  # ~publish_rate 30 Hz
        self.assertTrue(all(min(w[4]) > 0 for w in grip_samples), 'a pad does not touch')
        start = hold[0][3]
        slip = max(np.linalg.norm(w[3] - start) for w in hold)
        risen = hold[-1][2][2] - rest[2]
        carried = -np.mean([w[1] for w in hold])
        misses = f.state().collider_frame_misses - misses_before
        rospy.loginfo('robot grasp: the object rose %.1f mm; over %.1f s of holding (joint '
                      'states paused %.1f s) it moved %.2f mm relative to the palm; the fingers '
                      'carried %.3f N of its %.3f N weight (%+.2f %%); %d frame misses before '
                      'the hold, %d during it',
                      1e3 * risen, HOLD, PAUSE, 1e3 * slip, carried, weight,
                      100.0 * (carried / weight - 1.0), misses_before, misses)
        self.assertEqual(self.frames, {('robot/' + f, f) for f in FINGERS},
                         'each finger\'s wrench is in its link frame')
        self.assertGreaterEqual(risen, MIN_LIFT)
        self.assertLess(slip, MAX_SLIP)
        self.assertAlmostEqual(carried / weight, 1.0, delta=WEIGHT_TOLERANCE)


if __name__ == '__main__':
    rostest.rosrun(PKG, 'robot_grasp', RobotGraspTest)
