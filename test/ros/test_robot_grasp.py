#!/usr/bin/env python3
"""The robot scene end to end with the real tools: flsm_node reads urdf/gripper.urdf through
~robot_description, the real robot_state_publisher turns the joint states this test publishes
into the links' tf frames, and the gripper's pads close on the bunny resting on the ground and
lift it 10 cm.

Checked: the object rises at least MIN_LIFT; over HOLD seconds of holding it moves less than
MAX_SLIP relative to the palm (tf: flsm_object against the palm link); the fingers' vertical
contact forces (~contact_wrenches entries robot/finger_left and robot/finger_right, in the link
frames, turned into the world with tf) carry its weight, the lattice's mass (~state mass) times
g, within WEIGHT_TOLERANCE; and the joint states pause for PAUSE seconds in the middle of the hold
(so does robot_state_publisher's tf) without a single missed frame or a change of the hold.
"""

import math
import threading
import time
import unittest

import numpy as np
import rospy
import rostest
import tf2_ros
from sensor_msgs.msg import JointState

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


def smooth(s):
    """0 -> 1 with zero velocity at both ends."""
    s = min(1.0, max(0.0, s))
    return 0.5 - 0.5 * math.cos(math.pi * s)


class Joints(object):
    """Publishes /joint_states at 100 Hz along waypoints [(t, q)], each q held after its time and
    approached smoothly before; silent over the pauses [(t0, t1)] asked for."""

    def __init__(self, q):
        self.lock = threading.Lock()
        self.waypoints = [(0.0, np.asarray(q, float))]
        self.pauses = []
        self.pub = rospy.Publisher('/joint_states', JointState, queue_size=10)
        self.running = True
        self.thread = threading.Thread(target=self.run)
        self.thread.daemon = True
        self.thread.start()

    def go(self, duration, lift=None, left=None, right=None):
        """Moves to the joint values given over `duration` s from the end of the last move (or
        now); returns the time it gets there."""
        with self.lock:
            t0 = max(rospy.get_time(), self.waypoints[-1][0])
            q = self.waypoints[-1][1].copy()
            for k, v in enumerate((lift, left, right)):
                if v is not None:
                    q[k] = v
            self.waypoints.append((t0 + duration, q))
            return t0 + duration

    def pause(self, t0, t1):
        with self.lock:
            self.pauses.append((t0, t1))

    def at(self, t):
        with self.lock:
            w = list(self.waypoints)
        prev = w[0]
        for cur in w[1:]:
            if t < cur[0]:
                s = smooth((t - prev[0]) / max(1e-9, cur[0] - prev[0]))
                return prev[1] + s * (cur[1] - prev[1])
            prev = cur
        return prev[1]

    def run(self):
        rate = rospy.Rate(100.0)
        while self.running and not rospy.is_shutdown():
            now = rospy.Time.now()
            with self.lock:
                paused = any(a <= now.to_sec() < b for a, b in self.pauses)
            if not paused:
                msg = JointState()
                msg.header.stamp = now
                msg.name = list(JOINTS)
                msg.position = list(self.at(now.to_sec()))
                self.pub.publish(msg)
            rate.sleep()

    def stop(self):
        self.running = False
        self.thread.join()


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
        # Misses count only once a frame was seen: none at start-up, none over the pause.
        misses = f.state().collider_frame_misses
        rospy.loginfo('robot grasp: the object rose %.1f mm; over %.1f s of holding (joint '
                      'states paused %.1f s) it moved %.2f mm relative to the palm; the fingers '
                      'carried %.3f N of its %.3f N weight (%+.2f %%); %d frame misses',
                      1e3 * risen, HOLD, PAUSE, 1e3 * slip, carried, weight,
                      100.0 * (carried / weight - 1.0), misses)
        self.assertEqual(self.frames, {('robot/' + f, f) for f in FINGERS},
                         'each finger\'s wrench is in its link frame')
        self.assertGreaterEqual(risen, MIN_LIFT)
        self.assertLess(slip, MAX_SLIP)
        self.assertAlmostEqual(carried / weight, 1.0, delta=WEIGHT_TOLERANCE)
        self.assertEqual(misses, 0, 'a pause shorter than the stale time counted misses')


if __name__ == '__main__':
    rostest.rosrun(PKG, 'robot_grasp', RobotGraspTest)
