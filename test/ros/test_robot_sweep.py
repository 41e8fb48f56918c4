#!/usr/bin/env python3
"""An arm link swept through the object pushes it aside, with the real robot_state_publisher.

test/ros/sweep_arm.urdf's arm is an upright cylinder on a prismatic joint along x, through the
middle of the resting bunny; this test has the joint's states published (joint_states_player.py,
a process of its own), sweeping it from x = -START to +START and holding it there. Checked: the arm touched the object; the object was pushed out of
its way, by at least MIN_PUSH, in the direction opposite to the impulse the arm received (the sum
of its ~contact_wrenches force over the sweep, link frame turned into the world with tf), as
action and reaction must; in every ~particles cloud of the sweep, no particle's contact sphere
is inside the cylinder at the pose the node broadcast for it with the same stamp (the exact
cylinder, as the contact pass promises); nothing non-finite, no solver
reset; and the URDF's link 'inside', a sphere at the world origin inside the resting bunny, is
left out (~robot_exclude_overlapping, the default) instead of blowing the object apart.
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
from sensor_msgs import point_cloud2
from sensor_msgs.msg import PointCloud2

from deformable_flsm.msg import ContactWrenches
from flsm_testing import FlsmClient, finite

PKG = 'deformable_flsm'
# The arm's travel (m, from -START to +START along x) and how long it takes (s): 0.3 m/s on
# average (eased in and out).
START, SWEEP = 0.3, 2.0
# The arm's cylinder in the URDF: its axis at y = 0, radius ARM_RADIUS, from z = ARM_LOW to
# ARM_HIGH (m); the inside link: a sphere of INSIDE_RADIUS at the origin.
ARM_RADIUS, ARM_LOW, ARM_HIGH, INSIDE_RADIUS = 0.02, -0.08, 0.22, 0.02
# A particle's sphere may seem this far inside the arm (m): ~particles carries float32
# coordinates (rounding of 0.3 m to about 2e-8 m).
INSIDE_TOLERANCE = 1e-5
# Settled enough to start: no particle faster than this (m/s).
SETTLED = 0.005
# Pushed aside: the object's centre of mass moves at least this far (m) horizontally; a sweep
# that went through it without contact leaves it where it was.
MIN_PUSH = 0.05


def vector(v):
    return np.array([v.x, v.y, v.z])


def rotate(q, v):
    """v rotated by the unit quaternion q (geometry_msgs Quaternion)."""
    u = np.array([q.x, q.y, q.z])
    return v + 2.0 * np.cross(u, np.cross(u, v) + q.w * v)


class RobotSweepTest(unittest.TestCase):

    @classmethod
    def setUpClass(cls):
        rospy.init_node('test_robot_sweep')
        cls.lock = threading.Lock()
        player = os.path.join(os.path.dirname(os.path.abspath(__file__)), 'joint_states_player.py')
        cls.player = subprocess.Popen([sys.executable, player], stdin=subprocess.PIPE)
        cls.play([(0.0, [-START])])
        cls.flsm = FlsmClient()
        cls.tf_buffer = tf2_ros.Buffer()
        cls.tf_listener = tf2_ros.TransformListener(cls.tf_buffer)
        cls.samples = []  # (stamp, force on the arm in the world, contacts)
        cls.ids = set()
        rospy.Subscriber('/flsm_node/contact_wrenches', ContactWrenches, cls.on_wrenches,
                         queue_size=100)
        cls.clouds = []
        cls.recording = False
        rospy.Subscriber('/flsm_node/particles', PointCloud2, cls.on_cloud, queue_size=100)

    @classmethod
    def tearDownClass(cls):
        cls.player.stdin.close()
        cls.player.wait(timeout=10.0)

    @classmethod
    def play(cls, waypoints):
        """The sweep joint's waypoints [(t, [x])] from now on (see joint_states_player.py)."""
        line = json.dumps({'names': ['sweep'], 'waypoints': waypoints})
        cls.player.stdin.write((line + '\n').encode())
        cls.player.stdin.flush()

    @classmethod
    def on_cloud(cls, msg):
        with cls.lock:
            if cls.recording:
                cls.clouds.append(msg)

    @classmethod
    def on_wrenches(cls, msg):
        with cls.lock:
            cls.ids.update(msg.ids)
        for i, w, c in zip(msg.ids, msg.wrenches, msg.contacts):
            if i != 'robot/arm':
                continue
            try:
                link = cls.tf_buffer.lookup_transform('world', w.header.frame_id, rospy.Time(0))
            except tf2_ros.TransformException:
                return
            with cls.lock:
                cls.samples.append((msg.header.stamp.to_sec(),
                                    rotate(link.transform.rotation, vector(w.wrench.force)), c))

    def test_arm_pushes_the_object_aside(self):
        f = self.flsm
        s = f.wait_state(lambda s: s.sim_time > 2.0 and s.max_speed < SETTLED, 90.0)
        self.assertIsNotNone(s, 'the bunny did not come to rest on the ground')
        rest = f.particles()
        r = 0.5 * float(np.min(np.linalg.norm(np.diff(f.rest, axis=0), axis=1)))
        # The premise of the exclusion: the inside link does overlap the resting object.
        self.assertLess(np.min(np.linalg.norm(f.rest, axis=1)), INSIDE_RADIUS + r)
        before = rest.mean(axis=0)
        with self.lock:
            type(self).recording = True
        t0 = rospy.get_time() + 0.2
        t1 = t0 + SWEEP
        self.play([(t0, [-START]), (t1, [START])])
        while rospy.get_time() < t1 + 2.0 and not rospy.is_shutdown():
            time.sleep(0.05)
        with self.lock:
            type(self).recording = False
            clouds = list(self.clouds)
        after = f.particles()
        state = f.state()
        moved = after.mean(axis=0) - before
        with self.lock:
            sweep = [w for w in self.samples if t0 <= w[0] <= t1 + 0.5]
            ids = set(self.ids)
        self.assertTrue(sweep, 'no ~contact_wrenches entry for the arm')
        dt = 1.0 / 30.0  # ~publish_rate: each message averages its step; the sum is the impulse
        impulse = sum(w[1] for w in sweep) * dt
        touched = max(w[2] for w in sweep)
        rospy.loginfo('robot sweep: the object moved [%.1f, %.1f, %.1f] mm; the arm touched it '
                      'with up to %d particles and received an impulse [%.3f, %.3f, %.3f] N s',
                      *(list(1e3 * moved) + [touched] + list(impulse)))
        self.assertGreater(touched, 0, 'the arm never touched the object')
        self.assertGreater(np.linalg.norm(moved[:2]), MIN_PUSH, 'the object was not pushed aside')
        self.assertGreater(np.dot(moved[:2], -impulse[:2]), 0.0,
                           'the object did not move the way the arm pushed it')
        # Every contact sphere within the arm's height is outside it, in each cloud of the sweep
        # against the arm's pose of the same step (the node's tf flsm_collider/robot/arm/0).
        gaps = []
        for cloud in clouds:
            try:
                arm = self.tf_buffer.lookup_transform('world', 'flsm_collider/robot/arm/0',
                                                      cloud.header.stamp)
            except tf2_ros.TransformException:
                continue
            c = vector(arm.transform.translation)
            x = np.array(list(point_cloud2.read_points(cloud, field_names=('x', 'y', 'z'))))
            beside = x[(x[:, 2] > c[2] + ARM_LOW - 0.07) & (x[:, 2] < c[2] + ARM_HIGH - 0.07)]
            if len(beside):
                gaps.append(np.min(np.hypot(beside[:, 0] - c[0], beside[:, 1] - c[1])))
        self.assertGreater(len(gaps), 10, 'too few clouds with the arm\'s pose')
        gap = min(gaps) - ARM_RADIUS - r
        rospy.loginfo('robot sweep: over %d clouds the contact spheres came within %.3f mm of the '
                      'arm\'s surface', len(gaps), 1e3 * gap)
        self.assertGreater(gap, -INSIDE_TOLERANCE, 'a particle is inside the arm')
        self.assertTrue(finite(after.ravel()))
        self.assertEqual(state.solver_resets, 0)
        self.assertIn('robot/arm', ids)
        self.assertNotIn('robot/inside', ids, 'the link that starts inside the object joined')


if __name__ == '__main__':
    rostest.rosrun(PKG, 'robot_sweep', RobotSweepTest)
