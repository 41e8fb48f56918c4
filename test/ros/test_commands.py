#!/usr/bin/env python3
"""flsm_node's commands, end to end through its topics and services: drags (hard, spring,
several at once, moved, released, in another tf frame, by the RViz mouse), forces and impulses,
reset, pins, tf and dynamic_reconfigure. The scene is test/ros/coarse_bunny.yaml: the bunny on
a pinned base, no gravity, so that rest means the rest shape."""

import math
import time
import unittest

import numpy as np
import rospy
import rostest
import tf2_ros
from dynamic_reconfigure.client import Client as ReconfigureClient
from geometry_msgs.msg import TransformStamped
from visualization_msgs.msg import InteractiveMarkerFeedback

from deformable_flsm.msg import DragCommand, ForceCommand
from flsm_testing import FlsmClient, mouse_feedback, top_particle

PKG = 'deformable_flsm'


class CommandsTest(unittest.TestCase):

    @classmethod
    def setUpClass(cls):
        rospy.init_node('test_commands')
        cls.flsm = FlsmClient()
        cls.tf_buffer = tf2_ros.Buffer()
        cls.tf_listener = tf2_ros.TransformListener(cls.tf_buffer)
        # A second frame for commands given in another frame: world shifted by 10 cm in x.
        # (Debian's tf2_ros has no static_transform_publisher executable.)
        cls.static_tf = tf2_ros.StaticTransformBroadcaster()
        offset = TransformStamped()
        offset.header.stamp = rospy.Time.now()
        offset.header.frame_id = 'world'
        offset.child_frame_id = 'offset'
        offset.transform.translation.x = 0.1
        offset.transform.rotation.w = 1.0
        cls.static_tf.sendTransform(offset)

    def setUp(self):
        self.assertIsNotNone(self.flsm.settle(), 'the node did not come to rest')
        self.L = self.flsm.size

    def accepted(self):
        return self.flsm.state().accepted_commands

    # --- drags -----------------------------------------------------------------------------

    def test_hard_drag_reaches_target_then_returns_to_rest(self):
        f = self.flsm
        x = f.particles()
        p = top_particle(x)
        target = x[p] + np.array([0.2 * self.L, 0.0, 0.0])  # 20 % of the object size
        f.grab(p, tuple(target))
        reached = f.wait_particles(lambda y: np.linalg.norm(y[p] - target) < 1e-3 * self.L, 10.0)
        self.assertIsNotNone(reached, 'particle %d did not reach %s' % (p, target))
        s = f.wait_state(lambda s: s.active_drags == 1, 5.0)
        self.assertIsNotNone(s)
        self.assertGreater(s.max_displacement, 0.19 * self.L)
        f.release()
        # Pinned base, no gravity: the rest shape is the rest position. Wait until it is still
        # (idle), not for a moment when a swing passes through rest.
        s = f.wait_state(lambda s: s.active_drags == 0 and s.idle, 30.0)
        self.assertIsNotNone(s, 'no return to rest; last state %s' % f.state())
        self.assertLess(s.max_displacement, 0.01 * self.L)
        y = f.particles()
        self.assertLess(np.abs(y - f.rest).max(), 0.01 * self.L)

    def test_spring_drag_pulls_towards_target(self):
        f = self.flsm
        x = f.particles()
        p = top_particle(x)
        target = x[p] + np.array([0.0, 0.15 * self.L, 0.0])
        f.grab(p, tuple(target), stiffness=2.0)
        moved = f.wait_particles(lambda y: y[p][1] - x[p][1] > 0.05 * self.L, 10.0)
        self.assertIsNotNone(moved, 'a 2 N/m spring did not pull the ear towards its target')
        f.release()

    def test_several_drags_by_id_moved_and_released(self):
        f = self.flsm
        x = f.particles()
        top = top_particle(x)
        side = int(np.argmax(x[:, 0]))
        before = self.accepted()
        f.grab(top, tuple(x[top]), drag_id='ear')
        f.grab(side, tuple(x[side]), drag_id='side')
        self.assertIsNotNone(f.wait_state(lambda s: s.active_drags == 2, 5.0))
        # Move one target: only that particle follows.
        target = x[top] + np.array([0.0, 0.0, 0.1 * self.L])
        f.move(tuple(target), drag_id='ear')
        y = f.wait_particles(lambda y: np.linalg.norm(y[top] - target) < 1e-3 * self.L, 10.0)
        self.assertIsNotNone(y)
        self.assertLess(np.linalg.norm(y[side] - x[side]), 1e-3 * self.L)
        f.release('side')
        self.assertIsNotNone(f.wait_state(lambda s: s.active_drags == 1, 5.0))
        res = f.release_all()
        self.assertTrue(res.success)
        self.assertIn('1 drag', res.message)
        s = f.wait_state(lambda s: s.active_drags == 0, 5.0)
        self.assertIsNotNone(s)
        self.assertGreaterEqual(s.accepted_commands - before, 5)

    def test_grab_nearest_particles_to_a_point(self):
        f = self.flsm
        x = f.particles()
        p = top_particle(x)
        point = x[p] + np.array([0.001, 0.0, 0.0])  # just beside the ear's top particle
        target = x[p] + np.array([0.1 * self.L, 0.0, 0.0])
        f.drag(DragCommand.GRAB, 'near', point=tuple(point), count=1, target=tuple(target))
        y = f.wait_particles(lambda y: np.linalg.norm(y[p] - target) < 1e-3 * self.L, 10.0)
        self.assertIsNotNone(y, 'the particle nearest the point was not the one grabbed')
        f.release('near')

    def test_target_in_another_tf_frame(self):
        # setUpClass publishes "offset" = world shifted by (0.1, 0, 0).
        f = self.flsm
        x = f.particles()
        p = top_particle(x)
        target_world = x[p] + np.array([0.0, 0.0, 0.1 * self.L])
        target_offset = target_world - np.array([0.1, 0.0, 0.0])
        f.grab(p, tuple(target_offset), frame='offset')
        y = f.wait_particles(lambda y: np.linalg.norm(y[p] - target_world) < 1e-3 * self.L, 10.0)
        self.assertIsNotNone(y, 'the target was not transformed from frame offset')
        f.release()

    def test_rviz_mouse_drag(self):
        """RViz's interactive-marker feedback: press on the ear, move, release."""
        f = self.flsm
        pub = rospy.Publisher('/flsm_node/drag_marker/feedback', InteractiveMarkerFeedback,
                              queue_size=10)
        end = time.time() + 10.0
        while pub.get_num_connections() == 0 and time.time() < end:
            time.sleep(0.05)
        x = f.particles()
        p = top_particle(x)

        def feedback(event, pose_offset, mouse=None):
            mouse_feedback(pub, 'object', event, pose=pose_offset, point=mouse)

        feedback(InteractiveMarkerFeedback.MOUSE_DOWN, (0, 0, 0), mouse=x[p])
        self.assertIsNotNone(f.wait_state(lambda s: s.active_drags == 1, 5.0), 'no grab')
        delta = np.array([0.0, -0.1 * self.L, 0.05 * self.L])
        feedback(InteractiveMarkerFeedback.POSE_UPDATE, tuple(delta))
        # The mouse takes the particle under the cursor and its nearest neighbours, keeping
        # their arrangement around their centroid: the particle itself lands within about a
        # cell (~0.05 L at this resolution) of where the mouse took it.
        target = x[p] + delta
        y = f.wait_particles(lambda y: np.linalg.norm(y[p] - target) < 0.05 * self.L, 10.0)
        self.assertIsNotNone(y, 'the ear did not follow the mouse')
        self.assertEqual(f.state().active_drags, 1)
        feedback(InteractiveMarkerFeedback.MOUSE_UP, tuple(delta))
        self.assertIsNotNone(f.wait_state(lambda s: s.active_drags == 0, 5.0), 'no release')

    # --- forces ----------------------------------------------------------------------------

    def test_impulse_and_timed_force(self):
        f = self.flsm
        x = f.particles()
        p = top_particle(x)
        before = self.accepted()
        f.force(ForceCommand.IMPULSE, (0.02, 0.0, 0.0), point=tuple(x[p]), radius=0.03)
        s = f.wait_state(lambda s: s.kinetic_energy > 1e-6 and s.max_displacement > 1e-3, 5.0)
        self.assertIsNotNone(s, 'the impulse moved nothing')
        self.assertEqual(s.accepted_commands, before + 1)
        self.assertIsNotNone(f.settle())
        # A force acts for its duration of simulated time, then ends by itself.
        # On the particles within 3 cm of the ear's top (tens of grams: 0.2 N is ~10 m/s^2,
        # far under the limit of 1000 object sizes/s^2; a single surface particle can weigh
        # less than 0.1 g, for which the same force would be refused).
        rejected = f.state().rejected_commands
        f.force(ForceCommand.FORCE, (0.0, 0.2, 0.0), point=tuple(x[p]), radius=0.03,
                duration=0.5)
        s = f.wait_state(lambda s: s.active_forces == 1, 5.0)
        self.assertIsNotNone(s, 'no active force; last rejection: %s' % f.state().last_rejection)
        self.assertEqual(s.rejected_commands, rejected)
        t0 = s.sim_time
        s = f.wait_state(lambda s: s.active_forces == 0, 5.0)
        self.assertIsNotNone(s)
        self.assertGreaterEqual(s.sim_time - t0, 0.5 - 2.0 / 60.0)
        self.assertGreater(s.max_displacement, 1e-3)

    # --- services --------------------------------------------------------------------------

    def test_reset_goes_back_to_rest_at_once(self):
        f = self.flsm
        x = f.particles()
        p = top_particle(x)
        f.grab(p, tuple(x[p] + np.array([0.1 * self.L, 0, 0])))
        self.assertIsNotNone(f.wait_state(lambda s: s.max_displacement > 0.05 * self.L, 10.0))
        res = f.reset()
        self.assertTrue(res.success, res.message)
        s = f.wait_state(lambda s: s.active_drags == 0 and s.max_displacement < 1e-9, 2.0)
        self.assertIsNotNone(s, 'not at rest right after ~reset: %s' % f.state())
        self.assertLess(s.sim_time, 1.0)

    def test_pin_and_unpin_a_box(self):
        f = self.flsm
        x = f.particles()
        base = f.state().pinned_particles
        self.assertGreater(base, 0, 'the test scene pins the bunny base')
        top = x[:, 2].max()
        lo = (-1.0, -1.0, top - 0.03)
        hi = (1.0, 1.0, 1.0)
        inside = int(np.sum(f.rest[:, 2] >= top - 0.03))
        res = f.pin_box(lo, hi, True)
        self.assertTrue(res.success, res.message)
        self.assertEqual(res.particles, inside)
        self.assertEqual(res.pinned_total, base + inside)
        self.assertIsNotNone(f.wait_state(lambda s: s.pinned_particles == base + inside, 5.0))
        # A pinned particle does not follow a drag's target... its pin wins.
        p = top_particle(x)
        f.grab(p, tuple(x[p] + np.array([0.1 * self.L, 0, 0])))
        time.sleep(0.5)
        self.assertLess(np.linalg.norm(f.particles()[p] - x[p]), 1e-6)
        f.release()
        res = f.pin_box(lo, hi, False)
        self.assertTrue(res.success)
        self.assertEqual(res.pinned_total, base)
        # An inverted box is refused.
        res = f.pin_box(hi, lo, True)
        self.assertFalse(res.success)
        self.assertIn('exceeds', res.message)

    # --- tf --------------------------------------------------------------------------------

    def test_tf_frame_present_and_moving_with_the_object(self):
        f = self.flsm
        t = self.tf_buffer.lookup_transform('world', 'flsm_object', rospy.Time(0),
                                            rospy.Duration(5.0))
        at_rest = np.array([t.transform.translation.x, t.transform.translation.y,
                            t.transform.translation.z])
        # At rest the frame sits at the centre of mass (the particles' mean, for uniform cells
        # up to the partly filled surface cells: within a cell).
        self.assertLess(np.linalg.norm(at_rest - f.rest.mean(axis=0)), 0.05 * self.L)
        self.assertAlmostEqual(t.transform.rotation.w, 1.0, places=6)
        # Pull the whole free part of the object sideways: the frame follows.
        x = f.particles()
        f.drag(DragCommand.GRAB, 'bulk', point=tuple(x.mean(axis=0)), count=200,
               target=tuple(x.mean(axis=0) + np.array([0.1 * self.L, 0, 0])))
        moved = None
        end = time.time() + 10.0
        while time.time() < end:
            t = self.tf_buffer.lookup_transform('world', 'flsm_object', rospy.Time(0),
                                                rospy.Duration(1.0))
            if t.transform.translation.x - at_rest[0] > 0.02 * self.L:
                moved = t
                break
            time.sleep(0.05)
        self.assertIsNotNone(moved, 'flsm_object did not follow the object')
        age = (rospy.Time.now() - moved.header.stamp).to_sec()
        self.assertLess(age, 0.5, 'tf is stale')
        f.release('bulk')

    # --- dynamic_reconfigure ---------------------------------------------------------------

    def test_reconfigure_applies_through_set_params(self):
        f = self.flsm
        client = ReconfigureClient('/flsm_node', timeout=10.0)
        # alpha = 3 E h^2 / (rho dx^2 w (w + 1)) below the cap: proportional to E.
        alpha = f.state().alpha
        youngs = client.get_configuration(timeout=5.0)['youngs_modulus']
        client.update_configuration({'youngs_modulus': 2000.0})
        s = f.wait_state(lambda s: abs(s.alpha - alpha) > 1e-9, 5.0)
        self.assertIsNotNone(s, 'alpha did not follow youngs_modulus')
        a2000 = s.alpha
        client.update_configuration({'youngs_modulus': 1000.0})
        s = f.wait_state(lambda s: abs(s.alpha - a2000 / 2.0) < 1e-6 * a2000, 5.0)
        self.assertIsNotNone(s, 'alpha %g at 1000 Pa is not half of %g at 2000 Pa'
                             % (f.state().alpha, a2000))
        client.update_configuration({'youngs_modulus': youngs})
        self.assertIsNotNone(f.wait_state(lambda s: abs(s.alpha - alpha) < 1e-9, 5.0))
        # Gravity turns on and the (pinned) bunny sags; off again, it comes back.
        client.update_configuration({'gravity_z': -9.81})
        self.assertIsNotNone(f.wait_state(lambda s: s.max_displacement > 0.01 * self.L, 10.0))
        client.update_configuration({'gravity_z': 0.0})
        # The real-time factor and the publish rate.
        client.update_configuration({'real_time_factor': 0.5, 'publish_rate': 10.0})
        self.assertIsNotNone(f.wait_state(lambda s: s.requested_real_time_factor == 0.5, 5.0))
        time.sleep(1.0)
        n0, t0 = f.state_count(), time.time()
        time.sleep(3.0)
        rate = (f.state_count() - n0) / (time.time() - t0)
        client.update_configuration({'real_time_factor': 1.0, 'publish_rate': 30.0})
        self.assertAlmostEqual(rate, 10.0, delta=2.0)

    def test_reconfigure_never_switches_the_material_by_a_value(self):
        # A typo (-5) is clamped by dynamic_reconfigure to its minimum, 0, which once meant
        # "classic FastLSM, alpha = stiffness": now it is refused and nothing changes.
        f = self.flsm
        client = ReconfigureClient('/flsm_node', timeout=10.0)
        config = client.get_configuration(timeout=10.0)
        self.assertEqual(config['material'], 'youngs')
        modulus, alpha = config['youngs_modulus'], f.state().alpha
        refused = f.rejected('invalid_params')
        answer = client.update_configuration({'youngs_modulus': -5.0})
        self.assertEqual(answer['youngs_modulus'], modulus, 'the server did not keep the modulus')
        self.assertIsNotNone(f.wait_state(lambda s: self.flsm.rejected('invalid_params') ==
                                          refused + 1, 5.0), 'the negative modulus was not '
                             'counted as invalid_params')
        time.sleep(0.5)  # a change would have reached ~state by now
        self.assertEqual(f.state().alpha, alpha, 'the material changed')
        self.assertEqual(client.get_configuration(timeout=10.0)['youngs_modulus'], modulus)
        # A stiffness typo is clamped to 0 and refused too, not taken as a much softer material.
        answer = client.update_configuration({'stiffness': -1.0})
        self.assertEqual(answer['stiffness'], config['stiffness'], 'the server did not keep the stiffness')
        self.assertIsNotNone(f.wait_state(lambda s: self.flsm.rejected('invalid_params') ==
                                          refused + 2, 5.0), 'stiffness -1 was not counted as '
                             'invalid_params')
        time.sleep(0.5)
        self.assertEqual(f.state().alpha, alpha, 'the material changed')
        # The classic model is its own switch: alpha = stiffness, and back.
        client.update_configuration({'material': 'classic', 'stiffness': 0.5})
        self.assertIsNotNone(f.wait_state(lambda s: abs(s.alpha - 0.5) < 1e-12, 5.0),
                             'material classic did not give alpha = stiffness')
        client.update_configuration({'material': 'youngs', 'stiffness': 1.0})
        self.assertIsNotNone(f.wait_state(lambda s: abs(s.alpha - alpha) < 1e-12, 5.0),
                             'material youngs did not restore alpha')


if __name__ == '__main__':
    rostest.rosrun(PKG, 'commands', CommandsTest)
