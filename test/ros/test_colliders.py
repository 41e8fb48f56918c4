#!/usr/bin/env python3
"""Colliders in flsm_node: those of the parameters are there, one follows a tf frame that the
test moves (waiting uncounted before its frame appears; holding still, counted, when the frame
goes stale), and bad ~collider commands are
refused and counted by reason while the node keeps publishing."""

import math
import threading
import time
import unittest

import numpy as np
import rospy
import rostest
import tf2_ros
from geometry_msgs.msg import Point, Quaternion, TransformStamped, Twist, Vector3
from visualization_msgs.msg import Marker, MarkerArray

from deformable_flsm.msg import ColliderCommand, ContactWrenches
from flsm_testing import Counter, FlsmClient, finite

PKG = 'deformable_flsm'
FINGER_FRAME = 'test_finger'
PROBE_FRAME = 'test_probe'
# The finger's offset in its frame (test/ros/colliders.yaml).
FINGER_OFFSET = np.array([0.0, 0.0, 0.01])
# The frame moves along x at this speed (m/s), from this point, away from the bunny.
SPEED = 0.05
START = np.array([0.25, 0.25, 0.05])


class FrameBroadcaster(object):
    """Broadcasts frame `child` at 50 Hz, moving at SPEED along x while `on`."""

    def __init__(self, child=FINGER_FRAME):
        self.child = child
        self.br = tf2_ros.TransformBroadcaster()
        self.lock = threading.Lock()
        self.position = START.copy()
        self.on = False
        self.thread = threading.Thread(target=self.run, daemon=True)
        self.thread.start()

    def run(self):
        rate = rospy.Rate(50)
        last = time.time()
        while not rospy.is_shutdown():
            now = time.time()
            with self.lock:
                if self.on:
                    self.position[0] += SPEED * (now - last)
                    t = TransformStamped()
                    t.header.stamp = rospy.Time.now()
                    t.header.frame_id = 'world'
                    t.child_frame_id = self.child
                    t.transform.translation = Vector3(*self.position)
                    t.transform.rotation.w = 1.0
                    self.br.sendTransform(t)
            last = now
            rate.sleep()

    def where(self):
        with self.lock:
            return self.position.copy()


class CollidersTest(unittest.TestCase):

    @classmethod
    def setUpClass(cls):
        rospy.init_node('test_colliders')
        cls.flsm = FlsmClient()
        cls.pub = rospy.Publisher('/flsm_node/collider', ColliderCommand, queue_size=100)
        end = time.time() + 10.0
        while cls.pub.get_num_connections() == 0 and time.time() < end:
            time.sleep(0.05)
        cls.frame = FrameBroadcaster()
        # A frame of its own for the collider ADDed at run time, so that the parameters' finger
        # frame stays unseen until the scenario that needs it unseen turns it on.
        cls.probe_frame = FrameBroadcaster(PROBE_FRAME)

    def markers(self, timeout=5.0):
        """{namespace: [markers]} from the next ~colliders message."""
        msg = rospy.wait_for_message('/flsm_node/colliders', MarkerArray, timeout)
        out = {}
        for m in msg.markers:
            if m.action == Marker.ADD:
                out.setdefault(m.ns, []).append(m)
        return out

    def finger_position(self):
        m = self.markers().get('finger')
        if not m:
            return None
        p = m[0].pose.position
        return np.array([p.x, p.y, p.z])

    def test_follow_a_tf_frame_from_unseen_to_stale(self):
        # One scenario in its order: the finger's frame is never seen before it.
        self.parameters_and_an_unseen_frame()
        self.collider_follows_a_tf_frame()

    def parameters_and_an_unseen_frame(self):
        f = self.flsm
        # The ground and the wall are in; the finger waits for its frame, which has never been
        # seen: a second of samples finds it unknown, and none of them is a miss.
        time.sleep(1.0)  # the follower samples at the step rate, resting or not
        s = f.state()
        self.assertEqual(s.collider_frame_misses, 0, 'a frame not seen yet counted as missed')
        self.assertEqual(s.colliders, 2)
        shown = self.markers()
        self.assertEqual(sorted(shown), ['ground', 'wall'])
        wall = shown['wall'][0]
        self.assertEqual(wall.type, Marker.CUBE)
        self.assertAlmostEqual(wall.pose.position.x, 0.4)
        self.assertAlmostEqual(wall.scale.y, 0.3)
        msg = rospy.wait_for_message('/flsm_node/contact_wrenches', ContactWrenches, 5.0)
        self.assertEqual(sorted(msg.ids), ['ground', 'wall'])
        self.assertEqual([w.header.frame_id for w in msg.wrenches],
                         ['flsm_collider/' + i for i in msg.ids])

    def collider_follows_a_tf_frame(self):
        f = self.flsm
        with self.frame.lock:
            self.frame.on = True
        s = f.wait_state(lambda s: s.colliders == 3, 10.0)
        self.assertIsNotNone(s, 'the finger did not join when its frame appeared')
        self.assertFalse(s.idle, 'a moving collider must keep the simulation awake')
        errors = []
        first = None
        for _ in range(20):
            p = self.finger_position()
            expected = self.frame.where() + FINGER_OFFSET
            if first is None:
                first = p
            errors.append(np.linalg.norm(p - expected))
            time.sleep(0.1)
        travelled = np.linalg.norm(self.finger_position() - first)
        rospy.loginfo('follow: the finger marker travelled %.3f m; distance to its frame: median '
                      '%.4f m, max %.4f m (frame speed %.2f m/s)', travelled,
                      float(np.median(errors)), max(errors), SPEED)
        self.assertGreater(travelled, 0.05)
        # Within the motion of ~4 publish periods (sampling, stepping, publishing, delivery).
        self.assertLess(float(np.median(errors)), 0.01)
        # A still frame: the collider still, the simulation can rest.
        # The frame goes stale: the collider holds still and the misses are counted.
        misses = f.state().collider_frame_misses
        with self.frame.lock:
            self.frame.on = False
        time.sleep(1.5)
        held = self.finger_position()
        time.sleep(1.0)
        self.assertLess(np.linalg.norm(self.finger_position() - held), 1e-6,
                        'the collider moved on after its frame went stale')
        self.assertGreater(f.state().collider_frame_misses, misses)
        self.assertIsNotNone(f.wait_state(lambda s: s.idle, 30.0),
                             'the simulation did not rest with a stale frame')

    def command(self, action, collider_id='probe', kind='box', position=(0.4, 0.3, 0.0),
                quaternion=(0, 0, 0, 1), size=(0.05, 0.05, 0.05), radius=0.0, length=0.0,
                mesh='', friction=(0.6, 0.5), frame='', follow='', velocity=(0, 0, 0)):
        m = ColliderCommand()
        m.header.frame_id = frame
        m.action = action
        m.id = collider_id
        m.type = kind
        m.pose.position = Point(*position)
        m.pose.orientation = Quaternion(*quaternion)
        m.follow_frame = follow
        m.velocity = Twist(Vector3(*velocity), Vector3(0, 0, 0))
        m.size = Vector3(*size)
        m.radius = radius
        m.length = length
        m.mesh = mesh
        m.static_friction, m.kinetic_friction = friction
        return m

    def test_bad_commands_are_refused_and_counted(self):
        f = self.flsm
        nan = float('nan')
        A, M, R = ColliderCommand.ADD, ColliderCommand.MOVE, ColliderCommand.REMOVE
        bad = [
            ('bad_action', self.command(7)),
            ('bad_id', self.command(A, collider_id='')),
            ('bad_id', self.command(A, collider_id='x' * 65)),
            ('bad_type', self.command(A, kind='cone')),
            ('non_finite', self.command(A, position=(nan, 0, 0))),
            ('non_finite', self.command(A, size=(0.1, float('inf'), 0.1))),
            ('bad_orientation', self.command(A, quaternion=(0, 0, 0, 0))),
            ('bad_size', self.command(A, size=(0.1, -0.1, 0.1))),
            ('bad_size', self.command(A, kind='sphere', radius=0.0)),
            ('bad_size', self.command(A, kind='capsule', radius=0.01, length=-1.0)),
            ('bad_friction', self.command(A, friction=(0.2, 0.5))),
            ('bad_friction', self.command(A, friction=(0.5, -0.1))),
            ('bad_mesh', self.command(A, kind='mesh', mesh='/nonexistent/flsm/no_such.obj')),
            ('unknown_frame', self.command(A, frame='no_such_frame_flsm')),
            ('unknown_collider', self.command(M, collider_id='nobody')),
            ('unknown_collider', self.command(R, collider_id='nobody')),
            ('collider_follows_frame', self.command(M, collider_id='finger')),
            ('non_finite', self.command(M, collider_id='wall', velocity=(0, nan, 0))),
        ]
        s0 = f.state()
        before = {r: f.rejected(r) for r, _ in bad}
        states = Counter('/flsm_node/state', type(s0))
        wrenches = Counter('/flsm_node/contact_wrenches', ContactWrenches)
        for _, m in bad:
            self.pub.publish(m)
            time.sleep(0.05)
        s = f.wait_state(lambda s: s.rejected_commands >= s0.rejected_commands + len(bad), 10.0)
        self.assertIsNotNone(s, 'not every bad command was counted: %s' % f.state().reject_reasons)
        self.assertEqual(s.rejected_commands, s0.rejected_commands + len(bad))
        self.assertEqual(s.accepted_commands, s0.accepted_commands)
        expected = dict(before)
        for r, _ in bad:
            expected[r] += 1
        for r, n in expected.items():
            self.assertEqual(f.rejected(r), n, 'reason %s' % r)
        self.assertEqual(s.colliders, s0.colliders, 'a refused command changed the colliders')
        time.sleep(1.0)
        self.assertGreater(states.count, 20, 'the node stopped publishing ~state')
        self.assertGreater(wrenches.count, 20, 'the node stopped publishing ~contact_wrenches')
        msg = rospy.wait_for_message('/flsm_node/contact_wrenches', ContactWrenches, 5.0)
        for w in msg.wrenches:
            self.assertTrue(finite([w.wrench.force.x, w.wrench.force.y, w.wrench.force.z,
                                    w.wrench.torque.x, w.wrench.torque.y, w.wrench.torque.z]))

    def test_add_move_remove(self):
        f = self.flsm
        s0 = f.state()
        self.pub.publish(self.command(ColliderCommand.ADD, kind='capsule', radius=0.01,
                                      length=0.05))
        self.assertIsNotNone(f.wait_state(lambda s: s.colliders == s0.colliders + 1, 5.0))
        shown = self.markers()
        self.assertEqual(sorted(m.type for m in shown['probe']),
                         sorted([Marker.CYLINDER, Marker.SPHERE, Marker.SPHERE]))
        self.pub.publish(self.command(ColliderCommand.MOVE, position=(0.4, 0.35, 0.05)))
        end = time.time() + 5.0
        while time.time() < end:
            body = [m for m in self.markers()['probe'] if m.type == Marker.CYLINDER][0]
            if abs(body.pose.position.y - 0.35) < 1e-9:
                break
        self.assertAlmostEqual(body.pose.position.y, 0.35)
        self.assertAlmostEqual(body.pose.position.z, 0.05)
        self.pub.publish(self.command(ColliderCommand.REMOVE))
        self.assertIsNotNone(f.wait_state(lambda s: s.colliders == s0.colliders, 5.0))
        self.assertNotIn('probe', self.markers())
        self.assertEqual(f.state().accepted_commands, s0.accepted_commands + 3)

    def test_add_a_collider_that_follows_a_frame(self):
        frame = self.probe_frame
        with frame.lock:
            frame.on = True
        self.pub.publish(self.command(ColliderCommand.ADD, collider_id='finger2', kind='sphere',
                                      radius=0.01, position=(0.0, 0.0, -0.02),
                                      frame='no_such_frame_flsm', follow=PROBE_FRAME))
        error = float('inf')
        end = time.time() + 10.0
        while time.time() < end:
            m = self.markers().get('finger2')
            if m:
                p = m[0].pose.position
                error = np.linalg.norm(np.array([p.x, p.y, p.z]) - frame.where() -
                                       np.array([0.0, 0.0, -0.02]))
                if error < 0.01:
                    break
        self.assertLess(error, 0.01, 'the ADDed collider did not join and follow its frame')
        self.pub.publish(self.command(ColliderCommand.REMOVE, collider_id='finger2'))
        end = time.time() + 5.0
        while 'finger2' in self.markers() and time.time() < end:
            time.sleep(0.05)
        self.assertNotIn('finger2', self.markers(), 'REMOVE not applied')
        with frame.lock:
            frame.on = False


if __name__ == '__main__':
    rostest.rosrun(PKG, 'colliders', CollidersTest)
