#!/usr/bin/env python3
"""flsm_node with ~integrator: implicit on the default scene: the bunny, dropped onto the ground
at one sub-step per step, lands and comes to rest with the modulus asked for (never saturated),
every ~state and particle finite, no solver reset."""

import threading
import time
import unittest

import numpy as np
import rospy
import rostest

from sensor_msgs import point_cloud2
from sensor_msgs.msg import PointCloud2

from deformable_flsm.msg import SimulationState
from flsm_testing import finite

PKG = 'deformable_flsm'


class ImplicitTest(unittest.TestCase):

    def test_drops_and_comes_to_rest(self):
        rospy.init_node('test_implicit')
        lock = threading.Lock()
        seen = {'states': [], 'last': None}

        def on_state(s):
            with lock:
                seen['states'].append(s)
                seen['last'] = s

        rospy.Subscriber('/flsm_node/state', SimulationState, on_state, queue_size=100)
        start = rospy.wait_for_message('/flsm_node/particles', PointCloud2, timeout=60.0)
        x0 = np.array(list(point_cloud2.read_points(start, field_names=('x', 'y', 'z'))))
        # The bunny falls 10 cm and comes to rest on the ground after ~10 s of simulated time (the
        # explicit step alike: the slow rocking on the ground is damped by ambient damping alone);
        # 150 s of wall time for a busy machine, where the node runs slower than real time.
        end = time.time() + 150.0
        rested = None
        while time.time() < end and rested is None:
            with lock:
                s = seen['last']
            if s is not None and s.idle and s.sim_time > 1.0:
                rested = s
            time.sleep(0.1)
        self.assertIsNotNone(rested, 'the bunny did not come to rest')
        with lock:
            states = list(seen['states'])
        for s in states:
            self.assertTrue(finite([s.kinetic_energy, s.max_displacement, s.max_speed, s.shape_error]),
                            'non-finite ~state at sim time %.2f' % s.sim_time)
            self.assertFalse(s.stiffness_saturated, 'the implicit step never caps the modulus')
        self.assertEqual(rested.solver_resets, 0)
        cloud = rospy.wait_for_message('/flsm_node/particles', PointCloud2, timeout=10.0)
        x = np.array(list(point_cloud2.read_points(cloud, field_names=('x', 'y', 'z'))))
        self.assertTrue(np.isfinite(x).all())
        size = float(np.linalg.norm(x0.max(axis=0) - x0.min(axis=0)))
        # it fell (the ground is 10 cm below) and stands: its height kept within 10 %
        self.assertLess(x[:, 2].min(), x0[:, 2].min() - 0.05)
        height0 = x0[:, 2].max() - x0[:, 2].min()
        self.assertAlmostEqual(x[:, 2].max() - x[:, 2].min(), height0, delta=0.1 * height0)
        self.assertLess(rested.shape_error, 0.05 * size)


if __name__ == '__main__':
    rostest.rosrun(PKG, 'implicit', ImplicitTest)
