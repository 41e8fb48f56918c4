#!/usr/bin/env python3
"""Objects added and removed at run time: ~add_object builds an object from a parameter holding
one ~objects entry; its tf frame, ~objects/<name>/ topics, ~mesh marker and RViz mouse handle
appear and it takes drags by its name and by the mouse; ~remove_object takes it out (its marker
deleted with a DELETE action, its mouse handle erased, its topics unadvertised, its tf frame and
contact wrenches gone). A duplicate name, an unknown key,
a mesh that cannot be loaded, an object that starts inside another and an unknown name are
refused with a reason, counted, and the node simulates on."""

import threading
import time
import unittest

import numpy as np
import rospy
import rostest
from tf2_msgs.msg import TFMessage
from visualization_msgs.msg import InteractiveMarkerFeedback, InteractiveMarkerUpdate, Marker

from deformable_flsm.msg import ContactWrenches, DragCommand, SimulationState
from deformable_flsm.srv import AddObject, RemoveObject
from flsm_testing import ObjectsClient, mouse_feedback

PKG = 'deformable_flsm'
NODE = '/flsm_node'
CUBE = {'mesh': '/usr/share/glmark2/models/cube.3ds', 'mesh_scale': 0.04, 'mesh_rpy': [0, 0, 0],
        'resolution': 5}
# m: the drag lifts the added cube's top particle by this much (a quarter of the 8 cm cube); a
# hard drag holds its particle at the target to round-off.
LIFT = 0.02
HELD = 1e-6


def entry(name, pose, **keys):
    e = dict(CUBE, name=name, pose=pose)
    e.update(keys)
    return e


class ObjectsDynamicTest(unittest.TestCase):

    @classmethod
    def setUpClass(cls):
        rospy.init_node('test_objects_dynamic')
        cls.client = ObjectsClient(('left', 'right'))
        rospy.wait_for_service(NODE + '/add_object', timeout=30.0)
        cls.add_srv = rospy.ServiceProxy(NODE + '/add_object', AddObject)
        cls.remove_srv = rospy.ServiceProxy(NODE + '/remove_object', RemoveObject)
        cls.lock = threading.Lock()
        cls.frames = {}      # child frame -> wall time last seen on /tf
        cls.deleted = set()  # marker namespaces deleted on ~mesh
        cls.wrench_ids = set()
        cls.handles = set()  # the RViz mouse's handles on the interactive marker server
        cls.object_states = {}
        rospy.Subscriber(NODE + '/drag_marker/update', InteractiveMarkerUpdate, cls.on_handles,
                         queue_size=100)
        rospy.Subscriber(NODE + '/objects/top/state', SimulationState, cls.on_object_state,
                         callback_args='top', queue_size=10)
        cls.mouse = rospy.Publisher(NODE + '/drag_marker/feedback', InteractiveMarkerFeedback,
                                    queue_size=10)
        rospy.Subscriber('/tf', TFMessage, cls.on_tf, queue_size=100)
        rospy.Subscriber(NODE + '/mesh', Marker, cls.on_marker, queue_size=100)
        rospy.Subscriber(NODE + '/contact_wrenches', ContactWrenches, cls.on_wrenches, queue_size=10)
        cls.client.wait_sim_time(1.0, 120.0)

    @classmethod
    def on_tf(cls, msg):
        with cls.lock:
            for t in msg.transforms:
                cls.frames[t.child_frame_id] = time.time()

    @classmethod
    def on_marker(cls, msg):
        if msg.action == Marker.DELETE:
            with cls.lock:
                cls.deleted.add(msg.ns)

    @classmethod
    def on_handles(cls, msg):
        with cls.lock:
            cls.handles |= set(m.name for m in msg.markers)
            cls.handles -= set(msg.erases)

    @classmethod
    def on_object_state(cls, msg, name):
        with cls.lock:
            cls.object_states[name] = msg

    def drags_on(self, name):
        with self.lock:
            s = self.object_states.get(name)
        return None if s is None else s.active_drags

    @classmethod
    def on_wrenches(cls, msg):
        with cls.lock:
            cls.wrench_ids = set(msg.ids)

    def add(self, e, param='new_object'):
        rospy.set_param(NODE + '/' + param, e)
        return self.add_srv(param)

    def seen_frame(self, name, within=1.0):
        with self.lock:
            return time.time() - self.frames.get(name, 0.0) < within

    def wait(self, condition, timeout=20.0):
        end = time.time() + timeout
        while time.time() < end and not condition():
            time.sleep(0.05)
        return condition()

    def published(self, topic):
        return topic in [t for t, _ in rospy.get_published_topics()]

    def test_add_command_and_remove(self):
        # 'top' lands on the left cube, 'far' stands alone
        res = self.add(entry('top', [-0.2, 0, 0.16]))
        self.assertTrue(res.success, res.message)
        particles = res.particles
        res = self.add(entry('far', [0, 0.3, 0.05]), param='another')
        self.assertTrue(res.success, res.message)

        self.assertTrue(self.wait(lambda: self.seen_frame('top') and self.seen_frame('far')),
                        'no tf frame of the added objects')
        x = self.client.particles('top')
        self.assertEqual(len(x), particles)
        self.assertTrue(np.all(np.isfinite(x)))
        self.assertTrue(self.published(NODE + '/objects/top/state'))
        # it rests on the left cube: a wrench between them
        self.assertTrue(self.wait(lambda: any('top' in i and 'left' in i for i in self.wrench_ids)),
                        'no contact wrench between top and left: %s' % sorted(self.wrench_ids))

        # the RViz mouse: its handle appears; pressed on it, the mouse grabs the added object
        self.assertTrue(self.wait(lambda: 'top' in self.handles), 'no mouse handle for top')
        self.assertTrue(self.wait(lambda: self.mouse.get_num_connections() > 0))
        x = self.client.particles('top')
        mouse_feedback(self.mouse, 'top', InteractiveMarkerFeedback.MOUSE_DOWN,
                       point=x[int(np.argmax(x[:, 2]))])
        self.assertTrue(self.wait(lambda: self.drags_on('top') == 1), 'the mouse did not grab top')
        mouse_feedback(self.mouse, 'top', InteractiveMarkerFeedback.MOUSE_UP)
        self.assertTrue(self.wait(lambda: self.drags_on('top') == 0), 'the mouse did not let go')

        # a drag addressed to it by name lifts its top particle
        pub = rospy.Publisher(NODE + '/objects/top/drag', DragCommand, queue_size=10)
        self.assertTrue(self.wait(lambda: pub.get_num_connections() > 0))
        x = self.client.particles('top')
        p = int(np.argmax(x[:, 2]))
        target = x[p] + np.array([0.0, 0.0, LIFT])
        m = DragCommand()
        m.action = DragCommand.GRAB
        m.id = 'test'
        m.particle = p
        m.target.x, m.target.y, m.target.z = target
        pub.publish(m)
        self.assertTrue(self.wait(
            lambda: np.linalg.norm(self.client.particles('top')[p] - target) < HELD),
            'the added object was not dragged')

        # removed while a stream of drag moves to it arrives (the node's command thread inside
        # the object's drag callback as its subscription is shut down): its marker deleted, its
        # topics gone, no tf frame, no wrench; 'far' stays and the node goes on
        streaming = threading.Event()
        streaming.set()

        def stream():
            move = DragCommand()
            move.action = DragCommand.MOVE
            move.id = 'test'
            move.target.x, move.target.y, move.target.z = target
            while streaming.is_set() and not rospy.is_shutdown():
                pub.publish(move)
                time.sleep(0.002)

        streamer = threading.Thread(target=stream)
        streamer.start()
        try:
            time.sleep(0.5)
            res = self.remove_srv('top')
            time.sleep(0.5)
        finally:
            streaming.clear()
            streamer.join()
        self.assertTrue(res.success, res.message)
        self.assertTrue(self.wait(lambda: 'top' in self.deleted), 'no DELETE of its marker')
        self.assertTrue(self.wait(lambda: 'top' not in self.handles), 'its mouse handle stays')
        self.assertTrue(self.wait(lambda: not self.published(NODE + '/objects/top/particles')),
                        'its topics are still advertised')
        time.sleep(1.0)
        self.assertFalse(self.seen_frame('top', within=0.5), 'its tf frame is still sent')
        self.assertTrue(self.seen_frame('far', within=0.5))
        self.assertFalse(any('top' in i for i in self.wrench_ids), sorted(self.wrench_ids))

    def test_bad_additions_and_removals_are_refused_and_counted(self):
        before = self.client.state().rejected_commands
        cases = [
            (entry('left', [0.5, 0.5, 0.05]), 'already'),                  # a duplicate name
            (entry('odd', [0.5, 0.5, 0.05], colour='red'), 'unknown key'),  # a bad key
            (entry('ghost', [0.5, 0.5, 0.05], mesh='/nonexistent/x.obj'), 'x.obj'),
            (entry('inside', [0.2, 0, 0.05]), 'right'),                   # inside the right cube
        ]
        for e, why in cases:
            res = self.add(e, param='bad_object')
            self.assertFalse(res.success, e)
            self.assertIn(why, res.message)
        res = self.remove_srv('nobody')
        self.assertFalse(res.success)
        self.assertIn('nobody', res.message)
        self.assertTrue(self.wait(lambda: self.client.state().rejected_commands >= before + 5),
                        'the refusals are not counted')
        self.assertGreaterEqual(self.client.rejected('invalid_object'), 4)
        self.assertGreaterEqual(self.client.rejected('unknown_object'), 1)
        # the node simulates on: ~state keeps coming, the cubes' frames too
        stamp = self.client.state().header.stamp
        self.assertTrue(self.wait(lambda: self.client.state().header.stamp > stamp))
        self.assertTrue(self.wait(lambda: self.seen_frame('left', within=0.5)))


if __name__ == '__main__':
    rostest.rosrun(PKG, 'objects_dynamic', ObjectsDynamicTest)
