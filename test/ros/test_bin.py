#!/usr/bin/env python3
"""The bin (config/bin.yaml): twenty objects dropped into a box of five box colliders come to
rest inside it; nothing escapes, and no particle of one object ends inside another (from the
per-object clouds ~objects/<name>/particles)."""

import time
import unittest

import numpy as np
import rospy
import rostest
import tf2_ros
import yaml
import rospkg

from deformable_flsm.msg import DragCommand
from flsm_testing import ObjectsClient, half_spacing

PKG = 'deformable_flsm'
# s of simulated time for the pile to settle: the top layer falls 0.3 m in 0.25 s, the pile
# then settles within a few seconds (ambient damping 1/s).
SETTLE_S = 8.0
# At rest: over HOLD_S of simulated time each object's rigid frame (tf) moves less than
# REST_MOVE. A falling or sliding object moves centimetres in that time; 2 mm is a quarter of
# a particle's radius (~7.5 mm).
HOLD_S = 1.0
REST_MOVE = 0.002
# s of simulated time by which the node goes idle (the loop stops stepping): the pile settles
# within SETTLE_S, then creeps for a few seconds more.
IDLE_BY_S = 40.0


def bin_geometry():
    """Inner half-widths (x, y) and rim height of the box, from config/bin.yaml's colliders."""
    path = rospkg.RosPack().get_path(PKG) + '/config/bin.yaml'
    with open(path) as f:
        config = yaml.safe_load(f)
    boxes = {c['id']: c for c in config['colliders']}
    east, north = boxes['bin_wall_east'], boxes['bin_wall_north']
    floor = boxes['bin_floor']
    inner_x = east['position'][0] - 0.5 * east['size'][0]
    inner_y = north['position'][1] - 0.5 * north['size'][1]
    floor_top = floor['position'][2] + 0.5 * floor['size'][2]
    rim = east['position'][2] + 0.5 * east['size'][2]
    names = [o['name'] for o in config['objects']]
    return inner_x, inner_y, floor_top, rim, names


class BinTest(unittest.TestCase):

    @classmethod
    def setUpClass(cls):
        rospy.init_node('test_bin')
        cls.inner_x, cls.inner_y, cls.floor, cls.rim, cls.names = bin_geometry()
        cls.client = ObjectsClient(cls.names)
        cls.tf = tf2_ros.Buffer()
        cls.listener = tf2_ros.TransformListener(cls.tf)

    def frames(self):
        return {n: np.array([getattr(self.tf.lookup_transform('world', n, rospy.Time(0),
                                                              rospy.Duration(10.0))
                                     .transform.translation, a) for a in 'xyz'])
                for n in self.names}

    def test_the_objects_rest_inside_the_box_apart(self):
        self.assertEqual(len(self.names), 20)
        self.assertTrue(self.client.wait_sim_time(SETTLE_S, 300.0), 'the simulation does not run')
        before = self.frames()
        t0 = self.client.state().sim_time
        self.assertTrue(self.client.wait_sim_time(t0 + HOLD_S, 60.0))
        after = self.frames()
        moved = {n: float(np.linalg.norm(after[n] - before[n])) for n in self.names}
        self.assertLess(max(moved.values()), REST_MOVE,
                        'not at rest after %.0f s: %s' % (SETTLE_S, {n: round(m, 4) for n, m in
                                                               moved.items() if m >= REST_MOVE}))

        clouds = {n: self.client.particles(n) for n in self.names}
        radius = {n: half_spacing(x) for n, x in clouds.items()}
        for n, x in clouds.items():
            self.assertTrue(np.all(np.isfinite(x)), n)
            # Inside: every particle's centre within the walls and above the floor (its contact
            # sphere may overlap a wall by less than its radius, the contact's own tolerance),
            # and below the rim: nothing escaped over it.
            self.assertLessEqual(np.abs(x[:, 0]).max(), self.inner_x, n)
            self.assertLessEqual(np.abs(x[:, 1]).max(), self.inner_y, n)
            self.assertGreaterEqual(x[:, 2].min(), self.floor, n)
            self.assertLess(x[:, 2].max(), self.rim, n)
        # Apart: the particles of two objects no closer than the larger of their contact radii,
        # i.e. their contact spheres overlap by less than a radius (object contact's criterion:
        # penetration below the contact radius).
        worst = (np.inf, None)
        for i, a in enumerate(self.names):
            for b in self.names[i + 1:]:
                d = np.linalg.norm(clouds[a][:, None, :] - clouds[b][None, :, :], axis=2).min()
                limit = max(radius[a], radius[b])
                worst = min(worst, (d / limit, (a, b, d, limit)))
                self.assertGreaterEqual(d, limit, '%s and %s: particles %.4f m apart, contact '
                                        'radii %.4f and %.4f m' % (a, b, d, radius[a], radius[b]))
        rospy.loginfo('closest pair %s: %.4f m (limit %.4f m)', worst[1][:2], worst[1][2],
                      worst[1][3])

    def test_the_pile_goes_idle(self):
        # At rest the loop stops stepping (~state idle: no particle moved more than 2e-5 object
        # sizes over a second of simulated time). A pile that settled but jitters never does.
        idle_at = None
        end = time.time() + 300.0
        while time.time() < end and not rospy.is_shutdown():
            s = self.client.state()
            if s is not None and s.idle:
                idle_at = s.sim_time
                break
            if s is not None and s.sim_time > IDLE_BY_S:
                break
            time.sleep(0.05)
        self.assertIsNotNone(idle_at, 'the pile does not go idle within %.0f s of simulated '
                             'time (fastest particle %.3g m/s)' % (
                                 IDLE_BY_S, self.client.state().max_speed))
        rospy.loginfo('the pile went idle at %.1f s', idle_at)

    def test_z_a_drag_wakes_its_object_while_others_sleep_on(self):
        # ~object_sleep: an object at rest is not stepped, its ~objects/<name>/state idle; a
        # drag wakes the object it holds, and objects that nothing reaches sleep on.
        end = time.time() + 300.0
        while time.time() < end and not rospy.is_shutdown():
            states = [self.client.object_state(n) for n in self.names]
            if all(s is not None and s.idle for s in states):
                break
            time.sleep(0.1)
        asleep = [n for n in self.names if self.client.object_state(n).idle]
        self.assertEqual(len(asleep), len(self.names), 'not every object sleeps at rest: awake %s' %
                         [n for n in self.names if n not in asleep])
        frames = self.frames()
        name = 'bunny18'  # the top layer's, in the corner of x, y < 0
        start = frames[name]
        t0 = self.client.state().sim_time
        # held where it is, then lifted 5 cm at 5 cm/s, as a hand would
        self.client.drag(name, DragCommand.GRAB, drag_id='lift', point=tuple(start), count=7,
                         target=tuple(start))
        slept_on = set(self.names) - {name}
        woke = False
        while self.client.state().sim_time < t0 + 1.5 and time.time() < end:
            rise = min(0.05, 0.05 * max(0.0, self.client.state().sim_time - t0))
            self.client.drag(name, DragCommand.MOVE, drag_id='lift',
                             target=tuple(start + np.array([0.0, 0.0, rise])))
            woke = woke or not self.client.object_state(name).idle
            slept_on = {n for n in slept_on if self.client.object_state(n).idle}
            time.sleep(0.02)
        lifted = self.frames()[name][2] - start[2]
        self.client.drag(name, DragCommand.RELEASE, drag_id='lift')
        rospy.loginfo('the lifted object rose %.4f m; %d of %d others slept on: %s', lifted,
                      len(slept_on), len(self.names) - 1, sorted(slept_on))
        self.assertTrue(woke, 'the dragged object woke')
        self.assertGreater(lifted, 0.02, 'the dragged object was lifted')
        self.assertGreater(len(slept_on), 0, 'objects the drag did not reach sleep on')


if __name__ == '__main__':
    rostest.rosrun(PKG, 'bin', BinTest)
