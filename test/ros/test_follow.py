#!/usr/bin/env python3
"""~clock follow: this test serves /clock, as Gazebo or rosbag play --clock would: at half of
real time, then standing still, then on again, then back to where it began. flsm_node's states
(~state, ~particles) are stamped with its simulated time, which is never ahead of the /clock
served before them and never goes back, except once, when the clock went back and the scene was
reset; it keeps up with the clock to within a few steps."""

import threading
import time
import unittest

import rospy
import rostest
import tf2_ros
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import PointCloud2

from deformable_flsm.msg import SimulationState

PKG = 'deformable_flsm'
TIMEOUT_S = 60.0
START = 1000.0  # s: where the served clock begins, as a bag's would be anywhere
PACE = 0.5
PERIOD = 0.005  # s of wall time between two /clock messages
DT = 1.0 / 60.0  # ~time_step of config/flsm.yaml


class FollowTest(unittest.TestCase):

    def setUp(self):
        self.lock = threading.Lock()
        # the latest /clock sent so far (a message sent before the jump back may arrive after it)
        self.served = 0.0
        self.seen = []  # (topic, stamp, latest clock sent before it arrived)
        self.clock_pub = rospy.Publisher('/clock', Clock, queue_size=10)
        rospy.Subscriber('/flsm_node/state', SimulationState, self.on_msg('state'), queue_size=100)
        rospy.Subscriber('/flsm_node/particles', PointCloud2, self.on_msg('particles'), queue_size=100)
        self.tf = tf2_ros.Buffer()
        self.listener = tf2_ros.TransformListener(self.tf)

    def on_msg(self, topic):
        def record(msg):
            with self.lock:
                self.seen.append((topic, msg.header.stamp.to_sec(), self.served))
        return record

    def serve(self, t0, seconds, pace):
        """Serves /clock from t0 at `pace` for `seconds` of wall time; returns where it ended."""
        start = time.monotonic()
        t = t0
        while time.monotonic() - start < seconds:
            t = t0 + pace * (time.monotonic() - start)
            with self.lock:
                self.served = max(self.served, t)
            self.clock_pub.publish(Clock(clock=rospy.Time.from_sec(t)))
            time.sleep(PERIOD)
        return t

    def test_follows_never_ahead_never_back(self):
        rospy.wait_for_service('/flsm_node/reset', timeout=TIMEOUT_S)  # the node is up
        t = self.serve(START, 3.0, PACE)              # on at half speed
        with self.lock:
            self.assertTrue(self.seen, 'the node published nothing on the served clock')
            before_pause = len(self.seen)
        t = self.serve(t, 1.0, 0.0)                    # standing still
        with self.lock:
            during_pause = [s for s in self.seen[before_pause:] if s[1] > t + 1e-9]
        self.assertEqual(during_pause, [], 'stamps beyond a clock that stood still')
        t = self.serve(t, 1.5, PACE)                   # on again
        time.sleep(0.3)
        with self.lock:
            last_before_jump = max(s[1] for s in self.seen)
            count_before_jump = len(self.seen)
        self.assertGreater(last_before_jump, t - 5 * DT - 1.0 / 30.0,
                           'the node fell behind the clock it follows')
        self.serve(START, 1.5, PACE)                   # back to the start: the scene resets
        time.sleep(0.3)
        with self.lock:
            seen = list(self.seen)
        for topic, stamp, served in seen:
            self.assertLessEqual(stamp, served + 1e-6,
                                 '%s stamped %.4f ahead of the clock served before it (%.4f)' %
                                 (topic, stamp, served))
            self.assertGreaterEqual(stamp, START - 1e-6)
        for topic in ('state', 'particles'):
            stamps = [s[1] for s in seen if s[0] == topic]
            back = [(a, b) for a, b in zip(stamps, stamps[1:]) if b < a - 1e-9]
            self.assertEqual(len(back), 1, '%s went back %d times: %s' % (topic, len(back), back[:3]))
        after = [s[1] for s in seen[count_before_jump:]]
        self.assertTrue(after and min(after) < last_before_jump, 'the jump back was not followed')
        # tf goes on after the jump back too (the listener dropped what it had when the clock
        # went back): the object's frame at a stamp of the new run
        t = self.tf.lookup_transform('world', 'flsm_object', rospy.Time(0), rospy.Duration(2.0))
        self.assertLess(t.header.stamp.to_sec(), last_before_jump)


if __name__ == '__main__':
    rospy.init_node('test_follow')
    rostest.rosrun(PKG, 'follow', FollowTest)
