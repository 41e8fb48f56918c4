#!/usr/bin/env python3
"""~clock sim (flsm.launch sim_time:=true, ~real_time_factor 0.25): /clock advances at a quarter
of wall speed and the node's topics keep their rate in simulated time; a cloud and the object's
tf of one state share one stamp, the state's simulated time; a rospy client pacing itself with
rospy.Rate runs on it."""

import threading
import time
import unittest

import numpy as np
import rospy
import rostest
import tf2_ros
from rosgraph_msgs.msg import Clock
from sensor_msgs import point_cloud2
from sensor_msgs.msg import PointCloud2

from deformable_flsm.msg import SimulationState

PKG = 'deformable_flsm'
TIMEOUT_S = 60.0
FACTOR = 0.25
RATE = 30.0  # ~publish_rate of config/flsm.yaml


class SimTimeTest(unittest.TestCase):

    @classmethod
    def setUpClass(cls):
        rospy.wait_for_message('/flsm_node/state', SimulationState, timeout=TIMEOUT_S)

    def test_clock_runs_at_the_factor_and_topics_keep_their_rate_in_simulated_time(self):
        lock = threading.Lock()
        clocks, states = [], []

        def on_clock(msg):
            with lock:
                clocks.append((time.monotonic(), msg.clock.to_sec()))

        def on_state(msg):
            with lock:
                states.append(msg.header.stamp.to_sec())

        subs = [rospy.Subscriber('/clock', Clock, on_clock, queue_size=100),
                rospy.Subscriber('/flsm_node/state', SimulationState, on_state, queue_size=100)]
        time.sleep(6.0)
        for s in subs:
            s.unregister()
        with lock:
            clocks, states = list(clocks), list(states)
        self.assertGreater(len(clocks), 20)
        (w0, c0), (w1, c1) = clocks[0], clocks[-1]
        factor = (c1 - c0) / (w1 - w0)
        # paced by the wall clock: within 10 % of the asked factor (a busy machine may hold a
        # wait up, never speed it)
        self.assertGreater(factor, 0.9 * FACTOR, 'simulated %.3f s in %.3f s of wall' % (c1 - c0, w1 - w0))
        self.assertLess(factor, 1.05 * FACTOR, 'simulated %.3f s in %.3f s of wall' % (c1 - c0, w1 - w0))
        # /clock never goes back; ~state's stamps are simulated time, at ~publish_rate of it
        self.assertTrue(all(b[1] >= a[1] for a, b in zip(clocks, clocks[1:])))
        self.assertGreater(len(states), 10)
        rate = (len(states) - 1) / (states[-1] - states[0])
        self.assertGreater(rate, 0.8 * RATE, '~state at %.1f Hz of simulated time' % rate)
        self.assertLess(rate, 1.2 * RATE, '~state at %.1f Hz of simulated time' % rate)
        self.assertLessEqual(states[-1], c1 + 1e-9, 'a stamp ahead of /clock')

    def test_tf_at_each_clouds_stamp_is_the_frame_of_that_state(self):
        # In free fall the offset between the object's frame (its centre of mass) and the mean
        # of its particles stays what it was: with the frame of a state one step away it would
        # change by the fall of a step (g t dt, millimetres here).
        buf = tf2_ros.Buffer(rospy.Duration(30.0))
        tf2_ros.TransformListener(buf)
        clouds = []
        lock = threading.Lock()

        def on_cloud(msg):
            with lock:
                if len(clouds) < 40:
                    clouds.append(msg)

        sub = rospy.Subscriber('/flsm_node/particles', PointCloud2, on_cloud, queue_size=50)
        rate = rospy.Rate(RATE)  # on simulated time: a quarter of this in wall time
        start = time.monotonic()
        for _ in range(int(RATE)):
            rate.sleep()
        wall = time.monotonic() - start
        self.assertGreater(wall, 0.8 / FACTOR, 'rospy.Rate paced one simulated second in %.2f s' % wall)
        deadline = time.monotonic() + TIMEOUT_S
        while time.monotonic() < deadline:
            with lock:
                if len(clouds) >= 40:
                    break
            time.sleep(0.1)
        sub.unregister()
        time.sleep(0.5)  # the tf of the newest state is in the buffer (it goes out first anyway)
        offsets, stamps = [], []
        for msg in clouds:
            x = np.array([p[:3] for p in point_cloud2.read_points(msg, field_names=('x', 'y', 'z'))])
            t = buf.lookup_transform('world', 'flsm_object', msg.header.stamp, rospy.Duration(2.0))
            self.assertEqual(t.header.stamp, msg.header.stamp)
            origin = np.array([t.transform.translation.x, t.transform.translation.y,
                               t.transform.translation.z])
            offsets.append(origin - x.mean(axis=0))
            stamps.append(msg.header.stamp.to_sec())
        self.assertTrue(all(b > a for a, b in zip(stamps, stamps[1:])), 'stamps repeat or go back')
        spread = np.ptp(np.array(offsets), axis=0)
        self.assertLess(float(np.max(spread)), 2e-4,
                        'object frame against the particles drifts by %s m over %.2f s of fall' %
                        (spread, stamps[-1] - stamps[0]))


if __name__ == '__main__':
    rospy.init_node('test_sim_time')
    rostest.rosrun(PKG, 'sim_time', SimTimeTest)
