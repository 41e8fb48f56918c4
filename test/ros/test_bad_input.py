#!/usr/bin/env python3
"""flsm_node under bad input: NaN/Inf fields, out-of-range indices, unknown frames, absurd
magnitudes, zero and negative durations, bad boxes and a flood of commands. Every case must be
rejected and counted in ~state under its reason, and afterwards the node must still publish
finite data at its rate. A spring drag is held throughout, so that the node keeps stepping and
publishing (a resting node does not resend the ~mesh marker; test/ros/idle.test covers rest).
"""

import math
import time
import unittest

import numpy as np
import rospy
import rostest
from sensor_msgs.msg import PointCloud2
from visualization_msgs.msg import Marker

from deformable_flsm.msg import DragCommand, ForceCommand
from flsm_testing import FlsmClient, finite, top_particle

PKG = 'deformable_flsm'
NAN = float('nan')
INF = float('inf')
RATE = 30.0  # ~publish_rate of the test scene


class BadInputTest(unittest.TestCase):

    @classmethod
    def setUpClass(cls):
        rospy.init_node('test_bad_input')
        cls.flsm = FlsmClient()
        f = cls.flsm
        cls.L = f.size
        cls.n = f.state().particles
        x = f.particles()
        cls.top = top_particle(x)
        cls.x = x
        # Keep the simulation busy: a weak spring holding the ear where it is.
        f.grab(cls.top, tuple(x[cls.top]), drag_id='hold', stiffness=0.5)
        assert f.wait_state(lambda s: s.active_drags == 1, 10.0), 'hold drag not taken'

    def expect_rejected(self, reason, send, times=1):
        """Calls send(); ~state must count `times` more rejections for `reason`."""
        f = self.flsm
        before = f.rejected(reason)
        total = f.state().rejected_commands
        send()
        s = f.wait_state(lambda s: dict(zip(s.reject_reasons, s.reject_counts)).get(reason, 0)
                         >= before + times, 5.0)
        self.assertIsNotNone(s, 'not rejected as %s; last rejection: %r; reasons %s'
                             % (reason, f.state().last_rejection,
                                dict(zip(f.state().reject_reasons, f.state().reject_counts))))
        self.assertGreaterEqual(s.rejected_commands, total + times)
        self.assertTrue(s.last_rejection)

    # --- drag ------------------------------------------------------------------------------

    def test_drag_non_finite_fields(self):
        f, p = self.flsm, self.top
        self.expect_rejected('non_finite', lambda: f.grab(p, (NAN, 0, 0)))
        self.expect_rejected('non_finite', lambda: f.grab(p, (0, INF, 0)))
        self.expect_rejected('non_finite', lambda: f.grab(p, (0, 0, 0), stiffness=NAN))
        self.expect_rejected('non_finite', lambda: f.drag(DragCommand.GRAB, 'x', point=(-INF, 0, 0)))
        self.expect_rejected('non_finite', lambda: f.move((0, 0, NAN), drag_id='hold'))

    def test_drag_out_of_range_and_malformed(self):
        f, p = self.flsm, self.top
        self.expect_rejected('bad_index', lambda: f.grab(self.n, (0, 0, 0)))
        self.expect_rejected('bad_index', lambda: f.grab(2 ** 31 - 1, (0, 0, 0)))
        self.expect_rejected('bad_index', lambda: f.grab(-2, (0, 0, 0)))
        self.expect_rejected('bad_action', lambda: f.drag(9, 'x'))
        self.expect_rejected('bad_id', lambda: f.grab(p, (0, 0, 0), drag_id=''))
        self.expect_rejected('bad_id', lambda: f.grab(p, (0, 0, 0), drag_id='x' * 65))
        self.expect_rejected('bad_count', lambda: f.drag(DragCommand.GRAB, 'x', count=100000))
        self.expect_rejected('bad_stiffness', lambda: f.grab(p, (0, 0, 0), stiffness=-1.0))
        self.expect_rejected('unknown_drag', lambda: f.move((0, 0, 0), drag_id='nobody'))
        self.expect_rejected('unknown_drag', lambda: f.release('nobody'))

    def test_drag_absurd_magnitudes_and_unknown_frames(self):
        f, p = self.flsm, self.top
        self.expect_rejected('out_of_reach', lambda: f.grab(p, (1e30, 0, 0)))
        self.expect_rejected('out_of_reach', lambda: f.grab(p, (0, 0, 3.0 * self.L)))
        self.expect_rejected('out_of_reach', lambda: f.move((0, -1e30, 0), drag_id='hold'))
        self.expect_rejected('spring_too_stiff', lambda: f.grab(p, (0, 0, 0), stiffness=1e12))
        self.expect_rejected('unknown_frame', lambda: f.grab(p, (0, 0, 0), frame='no_such_frame'))

    # --- force -----------------------------------------------------------------------------

    def test_force_non_finite_and_malformed(self):
        f, p = self.flsm, self.top
        imp, frc = ForceCommand.IMPULSE, ForceCommand.FORCE
        self.expect_rejected('non_finite', lambda: f.force(frc, (NAN, 0, 0), particle=p, duration=1))
        self.expect_rejected('non_finite', lambda: f.force(imp, (0, INF, 0), particle=p))
        self.expect_rejected('non_finite', lambda: f.force(frc, (0, 0, 0), radius=INF, duration=1))
        self.expect_rejected('non_finite', lambda: f.force(frc, (0, 0, 1), particle=p, duration=NAN))
        self.expect_rejected('bad_action', lambda: f.force(5, (0, 0, 1), particle=p, duration=1))
        self.expect_rejected('bad_index', lambda: f.force(frc, (0, 0, 1), particle=self.n, duration=1))
        self.expect_rejected('bad_duration', lambda: f.force(frc, (0, 0, 1e-3), particle=p, duration=0))
        self.expect_rejected('bad_duration', lambda: f.force(frc, (0, 0, 1e-3), particle=p, duration=-1))
        self.expect_rejected('bad_duration', lambda: f.force(frc, (0, 0, 1e-3), particle=p, duration=1e6))
        self.expect_rejected('bad_radius', lambda: f.force(frc, (0, 0, 1e-3), radius=-0.01, duration=1))
        self.expect_rejected('bad_radius', lambda: f.force(frc, (0, 0, 1e-3), radius=10.0, duration=1))

    def test_force_absurd_magnitudes_and_unknown_frames(self):
        f, p = self.flsm, self.top
        imp, frc = ForceCommand.IMPULSE, ForceCommand.FORCE
        self.expect_rejected('too_large', lambda: f.force(frc, (1e30, 0, 0), particle=p, duration=1))
        self.expect_rejected('too_large', lambda: f.force(imp, (0, 0, -1e30), radius=0.05,
                                                          point=tuple(self.x.mean(axis=0))))
        self.expect_rejected('out_of_reach', lambda: f.force(imp, (0, 0, 1e-3), point=(0, 0, 1e30)))
        # Within reach but away from the object: nothing within the radius to push.
        self.expect_rejected('empty_selection', lambda: f.force(
            frc, (0, 0, 1e-3), point=(0, 0, 1.5 * self.L), radius=0.01, duration=1))
        self.expect_rejected('unknown_frame', lambda: f.force(imp, (0, 0, 1e-3), particle=p,
                                                              frame='no_such_frame'))

    # --- services --------------------------------------------------------------------------

    def test_pin_box_non_finite_and_inverted(self):
        f = self.flsm
        self.expect_rejected('non_finite', lambda: self.assertFalse(
            f.pin_box((NAN, 0, 0), (1, 1, 1)).success))
        self.expect_rejected('bad_box', lambda: self.assertFalse(
            f.pin_box((1, 1, 1), (0, 0, 0)).success))

    # --- floods ----------------------------------------------------------------------------

    def test_flood_of_commands(self):
        """5000 target updates as fast as rospy sends them: the node keeps publishing at rate,
        applies or refuses (queue_full) what reaches it, and never blocks."""
        f = self.flsm
        target = tuple(self.x[self.top])
        n0 = f.state_count()
        t0 = time.time()
        for k in range(5000):
            f.move((target[0], target[1], target[2] + 1e-4 * (k % 10)), drag_id='hold')
        sent = time.time() - t0
        time.sleep(1.0)
        rate = (f.state_count() - n0) / (time.time() - t0)
        self.assertGreater(rate, 0.7 * RATE, '~state fell to %.1f Hz during a %.1f s flood'
                           % (rate, sent))
        s = f.state()
        self.assertEqual(s.solver_resets, 0)

    # --- afterwards ------------------------------------------------------------------------

    def test_zz_still_alive_finite_and_at_rate(self):
        """Runs last (alphabetical order): everything above has been thrown at the node."""
        f = self.flsm
        s = f.state()
        self.assertEqual(s.solver_resets, 0)
        self.assertFalse(s.idle)
        self.assertTrue(finite([s.sim_time, s.step_time, s.real_time_factor, s.kinetic_energy,
                                s.max_displacement, s.max_speed, s.shape_error, s.alpha]))
        # Rates of the heavy topics, counted by their own subscribers.
        counts = {'particles': 0, 'mesh': 0}
        last = {}

        def on_cloud(msg):
            counts['particles'] += 1
            last['particles'] = msg

        def on_mesh(msg):
            counts['mesh'] += 1
            last['mesh'] = msg

        subs = [rospy.Subscriber('/flsm_node/particles', PointCloud2, on_cloud, queue_size=5),
                rospy.Subscriber('/flsm_node/mesh', Marker, on_mesh, queue_size=5)]
        time.sleep(1.0)  # connect
        c0 = dict(counts)
        time.sleep(3.0)
        for sub in subs:
            sub.unregister()
        for topic in counts:
            rate = (counts[topic] - c0[topic]) / 3.0
            self.assertAlmostEqual(rate, RATE, delta=0.2 * RATE, msg='~%s at %.1f Hz' % (topic, rate))
        x = self.flsm.particles(with_displacement=True)
        self.assertTrue(np.all(np.isfinite(x)))
        pts = last['mesh'].points
        self.assertTrue(all(math.isfinite(p.x) and math.isfinite(p.y) and math.isfinite(p.z)
                            for p in pts))
        # The hold drag survived the storm, and the object is where a weak spring keeps it.
        self.assertEqual(f.state().active_drags, 1)
        self.assertLess(f.state().max_displacement, 0.5 * self.L)


if __name__ == '__main__':
    rostest.rosrun(PKG, 'bad_input', BadInputTest)
