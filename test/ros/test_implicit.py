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
        # The bunny falls 2 cm and settles on the ground within ~5 s of simulated time (the slow
        # rocking on the ground is damped by ambient damping alone); 150 s of wall time for a busy
        # machine, where the node runs slower than real time. At rest: kinetic energy under 1e-6 J
        # (~1.5 mm/s for its 0.8 kg) for 2 s of simulated time. (The node's own idle test, 4 um in
        # 1 s, is not reached: the implicit step's contacts keep a jitter of ~0.3 mm/s.)
        end = time.time() + 150.0
        rested, quiet_since = None, None
        while time.time() < end and rested is None:
            with lock:
                s = seen['last']
            if s is not None and s.sim_time > 1.0 and s.kinetic_energy < 1e-6:
                quiet_since = s.sim_time if quiet_since is None else quiet_since
                if s.sim_time - quiet_since > 2.0:
                    rested = s
            elif s is not None:
                quiet_since = None
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
        # it stands on the ground: measured 0.875 of its height at the start (30 kPa: the ears and
        # back sag under its weight); lying on its side it would keep under 0.7
        height0 = x0[:, 2].max() - x0[:, 2].min()
        self.assertGreater(x[:, 2].max() - x[:, 2].min(), 0.8 * height0)
        self.assertLess(rested.shape_error, 0.05 * size)


if __name__ == '__main__':
    rostest.rosrun(PKG, 'implicit', ImplicitTest)
