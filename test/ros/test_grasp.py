#!/usr/bin/env python3
"""The grasp scene end to end: two box fingers on tf frames that this node broadcasts close on
the bunny resting on the ground and lift it 10 cm. With friction 1 the bunny stays between the
fingers (it slips by less than 5 mm over 5 s, measured between the fingers' frame and the
object's tf frame flsm_object) and the fingers' vertical contact forces (~contact_wrenches)
carry its weight (~state mass times g) within 5 %; with friction 0.05 it slips out.

Parameters (private): ~squeeze (m, default SQUEEZE), ~friction (static = kinetic) to give the fingers through ~collider before
the grasp (0: keep those of the parameters), ~expect "hold" or "slip"."""

import math
import multiprocessing
import threading
import time
import unittest

import numpy as np
import rospy
import rostest
import tf2_ros
from sensor_msgs.msg import Image
from geometry_msgs.msg import Point, Quaternion, TransformStamped, Vector3

from deformable_flsm.msg import ColliderCommand, ContactWrenches
from flsm_testing import FlsmClient

PKG = 'deformable_flsm'
FINGERS = ('finger_left', 'finger_right')
GRAVITY = 9.81
# The grasp: each finger's inner face goes SQUEEZE m into the object's contact surface at the
# height of its centre of mass; the fingers then lift it LIFT m.
SQUEEZE = 0.035
LIFT = 0.10
# Seconds: the fingers come from their parking places to either side of the object, close,
# wait for the grip to settle, lift, and wait for the lifted object to stop swinging; then HOLD
# seconds of holding are measured.
APPROACH, CLOSE, GRIP, RAISE, SWING, HOLD = 2.0, 2.0, 1.0, 2.0, 1.5, 5.0
# Holding: the object moves less than this relative to the fingers over HOLD (m), and the
# fingers' vertical forces carry its weight within this fraction.
MAX_SLIP = 0.005
WEIGHT_TOLERANCE = 0.05
# The object is still enough to aim at when no particle is faster than this (m/s).
SETTLED = 0.005
# Wall seconds to wait for that: on a busy machine the node runs slower than real time (it
# says so in ~state.real_time_factor), and the settling takes simulated seconds.
WAIT_REST = 170.0
# Slipping: with low friction the object ends at least this far below where the fingers took it
# (m): it slid out of the grip (its share of the lift is lost).
MIN_SLIP_OUT = 0.03


def smooth(s):
    """0 -> 1 with zero velocity at both ends."""
    s = min(1.0, max(0.0, s))
    return 0.5 - 0.5 * math.cos(math.pi * s)


class Path(object):
    """Finger positions along waypoints [(t, left, right)], each held after its time and
    approached smoothly before it."""

    def __init__(self, left, right):
        self.waypoints = [(0.0, np.asarray(left, float), np.asarray(right, float))]

    def append(self, t, left, right):
        self.waypoints.append((t, np.asarray(left, float), np.asarray(right, float)))

    def at(self, t):
        """(left, right) positions at ROS time t."""
        w = self.waypoints
        prev = w[0]
        for cur in w[1:]:
            if t < cur[0]:
                s = smooth((t - prev[0]) / max(1e-9, cur[0] - prev[0]))
                return (prev[1] + s * (cur[1] - prev[1]), prev[2] + s * (cur[2] - prev[2]))
            prev = cur
        return prev[1], prev[2]


def broadcast_fingers(conn, left, right):
    """The finger frames' broadcaster, in a process of its own: at 100 Hz, in 'world', along the
    path whose waypoints arrive on `conn` (None ends it). The node holds a followed collider
    still when its frame's newest transform is 0.5 s old; a thread of the test process would
    share that process's interpreter lock with every message the test reads (tf, ~state,
    wrenches, ~particles), and be the first thing to starve on a busy machine. Here nothing else
    runs, and it asks for a higher priority where it may."""
    import os
    try:
        os.setpriority(os.PRIO_PROCESS, 0, -5)
    except (OSError, AttributeError):
        pass  # no privilege: the ordinary priority, still with nothing else in the process
    # argv=[]: the spawned interpreter was given the test's own arguments, rostest's
    # __name:= among them, and a second node of that name would shut the test down.
    rospy.init_node('test_grasp_fingers', argv=[], anonymous=True, disable_signals=True)
    path = Path(left, right)
    broadcaster = tf2_ros.TransformBroadcaster()
    rate = rospy.Rate(100.0)
    while not rospy.is_shutdown():
        while conn.poll():
            waypoint = conn.recv()
            if waypoint is None:
                return
            path.append(*waypoint)
        now = rospy.Time.now()
        msgs = []
        for name, p in zip(FINGERS, path.at(now.to_sec())):
            t = TransformStamped()
            t.header.stamp = now
            t.header.frame_id = 'world'
            t.child_frame_id = name
            t.transform.translation = Vector3(*p)
            t.transform.rotation.w = 1.0
            msgs.append(t)
        broadcaster.sendTransform(msgs)
        rate.sleep()


class Fingers(object):
    """Moves the finger frames: the waypoints go to broadcast_fingers() in its own process, and
    are kept here to say where the fingers were at a given time."""

    def __init__(self, left, right):
        self.lock = threading.Lock()
        self.path = Path(left, right)
        context = multiprocessing.get_context('spawn')  # a fresh interpreter, not a fork of rospy
        self.conn, child = context.Pipe()
        self.process = context.Process(target=broadcast_fingers, args=(child, left, right),
                                       daemon=True)
        self.process.start()

    def go(self, duration, left, right):
        """Moves to (left, right) over `duration` s from the end of the last move (or now)."""
        with self.lock:
            t0 = max(rospy.get_time(), self.path.waypoints[-1][0])
            if t0 > self.path.waypoints[-1][0]:
                # Held where they are until now: without this waypoint the move would be
                # interpolated from the last one's time (the parking's is 0), a jump at once,
                # which the node follows as a collider sweeping through the object at tens of m/s.
                self.path.append(t0, *self.path.at(t0))
                self.conn.send(self.path.waypoints[-1])
            self.path.append(t0 + duration, left, right)
            self.conn.send(self.path.waypoints[-1])
            return t0 + duration

    def at(self, t):
        """(left, right) positions at ROS time t."""
        with self.lock:
            return self.path.at(t)

    def stop(self):
        self.conn.send(None)
        self.process.join(5.0)
        if self.process.is_alive():
            self.process.terminate()


class GraspTest(unittest.TestCase):

    @classmethod
    def setUpClass(cls):
        rospy.init_node('test_grasp')
        cls.friction = float(rospy.get_param('~friction', 0.0))
        cls.expect = rospy.get_param('~expect', 'hold')
        cls.squeeze = float(rospy.get_param('~squeeze', SQUEEZE))
        params = rospy.get_param('/flsm_node/colliders')
        cls.specs = {c['id']: c for c in params if c['id'] in FINGERS}
        cls.size = {k: np.array(v['size'], float) for k, v in cls.specs.items()}
        # Parked far to the sides at ground level until the object rests.
        cls.fingers = Fingers((0.0, -0.4, -0.05), (0.0, 0.4, -0.05))
        cls.flsm = FlsmClient()
        cls.tf_buffer = tf2_ros.Buffer()
        cls.tf_listener = tf2_ros.TransformListener(cls.tf_buffer)
        cls.wrenches = []
        cls.wrench_lock = threading.Lock()
        rospy.Subscriber('/flsm_node/contact_wrenches', ContactWrenches, cls.on_wrenches,
                         queue_size=50)
        # the fingers' tactile pads (grasp_scene.launch): pressure images and the fingers'
        # forces, by stamp
        cls.pressed = {f: {} for f in FINGERS}
        cls.finger_force = {f: {} for f in FINGERS}
        for finger, pad in zip(FINGERS, ('left', 'right')):
            rospy.Subscriber('/flsm_node/tactile/%s/pressure' % pad, Image, cls.on_pressure(finger),
                             queue_size=50)

    @classmethod
    def tearDownClass(cls):
        cls.fingers.stop()

    @classmethod
    def on_pressure(cls, finger):
        def on(msg):
            p = np.frombuffer(msg.data, dtype=np.float32)
            # the pad covers the finger's x-z face: taxels of (size x / cols) (size z / rows)
            area = (cls.size[finger][0] / msg.width) * (cls.size[finger][2] / msg.height)
            with cls.wrench_lock:
                cls.pressed[finger][msg.header.stamp] = float(p.sum()) * area
        return on

    @classmethod
    def on_wrenches(cls, msg):
        with cls.wrench_lock:
            for i, w in zip(msg.ids, msg.wrenches):
                if i in FINGERS:
                    f = w.wrench.force
                    cls.finger_force[i][msg.header.stamp] = np.array([f.x, f.y, f.z])
        fz = {i: w.wrench.force.z for i, w in zip(msg.ids, msg.wrenches)}
        contacts = dict(zip(msg.ids, msg.contacts))
        if not all(f in fz for f in FINGERS):
            return
        try:
            obj = cls.tf_buffer.lookup_transform('world', 'flsm_object', rospy.Time(0))
        except tf2_ros.TransformException:
            return
        t = obj.header.stamp.to_sec()
        left, right = cls.fingers.at(t)
        p = obj.transform.translation
        relative = np.array([p.x, p.y, p.z]) - 0.5 * (left + right)
        with cls.wrench_lock:
            cls.wrenches.append((msg.header.stamp.to_sec(), sum(fz[f] for f in FINGERS),
                                 contacts.get('ground', 0), relative,
                                 [contacts[f] for f in FINGERS]))

    def samples(self, t0, t1):
        with self.wrench_lock:
            return [w for w in self.wrenches if t0 <= w[0] <= t1]

    def set_friction(self, mu):
        pub = rospy.Publisher('/flsm_node/collider', ColliderCommand, queue_size=10)
        end = time.time() + 10.0
        while pub.get_num_connections() == 0 and time.time() < end:
            time.sleep(0.05)
        # Read before publishing: a ~state that already counts these commands may arrive
        # between the publish and a later read, and the wait would then ask for two more.
        accepted = self.flsm.state().accepted_commands
        for name in FINGERS:
            spec = self.specs[name]
            m = ColliderCommand()
            m.action = ColliderCommand.ADD
            m.id = name
            m.type = spec['type']
            m.follow_frame = spec['frame_id']
            m.pose.position = Point(*spec.get('position', [0.0, 0.0, 0.0]))
            m.pose.orientation = Quaternion(*spec.get('orientation', [0.0, 0.0, 0.0, 1.0]))
            m.size = Vector3(*spec['size'])
            m.static_friction = mu
            m.kinetic_friction = mu
            pub.publish(m)
        self.assertIsNotNone(self.flsm.wait_state(lambda s: s.accepted_commands >= accepted + 2,
                                                  10.0),
                             'friction %.3g not accepted in 10 s (last rejection: %r)'
                             % (mu, self.flsm.state().last_rejection))

    def aim(self):
        """Waits for the object to settle; returns its weight and the fingers' open and closed
        positions (left, right) either side of it at the height of its centre of mass."""
        f = self.flsm
        if self.friction > 0.0:
            self.set_friction(self.friction)
        # Settled enough to aim at: every particle slower than SETTLED m/s (the simulation's idle
        # test asks for equilibrium to micrometres, which the grasp does not need).
        s = f.wait_state(lambda s: s.sim_time > 2.0 and s.max_speed < SETTLED, WAIT_REST)
        self.assertIsNotNone(s, 'the bunny did not come to rest on the ground')
        weight = s.mass * GRAVITY
        x = f.particles()
        com = np.mean(x, axis=0)  # equal-mass particles inside; near enough for aiming
        try:
            obj = self.tf_buffer.lookup_transform('world', 'flsm_object', rospy.Time(0),
                                                  rospy.Duration(5.0))
            com = np.array([obj.transform.translation.x, obj.transform.translation.y,
                            obj.transform.translation.z])
        except tf2_ros.TransformException:
            pass
        # The body's extent across y at the height of the centre of mass, around it in x.
        band = x[(np.abs(x[:, 2] - com[2]) < 0.015) & (np.abs(x[:, 0] - com[0]) < 0.03)]
        self.assertGreater(len(band), 3)
        spacing = float(np.min(np.linalg.norm(x[1:] - x[:-1], axis=1)[
            np.linalg.norm(x[1:] - x[:-1], axis=1) > 1e-6]))
        surface = 0.5 * spacing  # contact spheres of half the spacing (~contact_radius 0)
        lo, hi = band[:, 1].min() - surface, band[:, 1].max() + surface
        half = 0.5 * self.size['finger_left'][1]
        centre_x, centre_z = com[0], com[2]
        open_l = (centre_x, lo - 0.03 - half, centre_z)
        open_r = (centre_x, hi + 0.03 + half, centre_z)
        closed_l = (centre_x, lo + self.squeeze - half, centre_z)
        closed_r = (centre_x, hi - self.squeeze + half, centre_z)
        rospy.loginfo('grasp: weight %.3f N, object %.3f m across y at z %.3f; fingers close '
                      'from y %.3f / %.3f to %.3f / %.3f', weight, hi - lo, centre_z,
                      open_l[1], open_r[1], closed_l[1], closed_r[1])
        return weight, open_l, open_r, closed_l, closed_r

    def check_pads(self):
        """The tactile pads: what each presses on its taxels adds up to its finger's force along
        the pad's normal (finger_left's pad faces +y, finger_right's -y; the object pushes the
        fingers apart), within 1 %, in every state both were sent for while gripping. (Not
        while the object slips out: squeezed past the pads it also touches the fingers' backs,
        which the pads do not cover and the finger's force nets out.)"""
        compared, worst = 0, 0.0
        pads = zip(FINGERS, (1.0, -1.0)) if self.expect == 'hold' else ()
        with self.wrench_lock:
            for finger, sign in pads:
                for stamp, pa in self.pressed[finger].items():
                    f = self.finger_force[finger].get(stamp)
                    normal = None if f is None else -sign * f[1]
                    if normal is None or normal < 0.1:
                        continue
                    self.assertAlmostEqual(pa, normal, delta=0.01 * normal,
                                           msg='%s pad %.4f N against the finger force %.4f N' % (finger, pa, normal))
                    compared += 1
                    worst = max(worst, abs(pa / normal - 1.0))
        rospy.loginfo('grasp: tactile pads against the finger forces in %d states: within %.3f %%',
                      compared, 100.0 * worst)
        if self.expect == 'hold':
            self.assertGreater(compared, 20, 'too few tactile frames while gripping')

    def test_grasp_and_lift(self):
        weight, open_l, open_r, closed_l, closed_r = self.aim()
        up = np.array([0.0, 0.0, LIFT])
        fg = self.fingers
        fg.go(APPROACH, open_l, open_r)
        fg.go(CLOSE, closed_l, closed_r)
        gripped = fg.go(GRIP, closed_l, closed_r)
        lifted = fg.go(RAISE, np.array(closed_l) + up, np.array(closed_r) + up)
        t0 = lifted + SWING
        t1 = t0 + HOLD
        while rospy.get_time() < t1 + 0.3 and not rospy.is_shutdown():
            time.sleep(0.1)
        grip = self.samples(gripped - 0.3, gripped)
        hold = self.samples(t0, t1)
        self.assertGreater(len(grip), 3)
        self.assertGreater(len(hold), 0.5 * HOLD * 30.0 / 2)  # ~publish rate
        self.assertTrue(all(min(w[4]) > 0 for w in grip), 'a finger does not touch the object')
        start = hold[0][3]
        slip = max(np.linalg.norm(w[3] - start) for w in hold)
        drop = start[2] - hold[-1][3][2]
        carried = -np.mean([w[1] for w in hold])
        on_ground = max(w[2] for w in hold)
        final_drop = (self.samples(gripped - 0.3, gripped)[-1][3][2] - hold[-1][3][2])
        rospy.loginfo('grasp (%s): over %.1f s of holding %.0f mm up, the object moved %.2f mm '
                      'relative to the fingers (%.2f mm down; %.1f mm below where it was '
                      'gripped); the fingers carried %.3f N of its %.3f N weight (%.2f %%); '
                      'ground contacts up to %d', self.expect, HOLD, 1e3 * LIFT, 1e3 * slip,
                      1e3 * drop, 1e3 * final_drop, carried, weight,
                      100.0 * (carried / weight - 1.0), on_ground)
        self.check_pads()
        if self.expect == 'hold':
            # (The hanging jelly sags: its lowest particles may still brush the ground; what the
            # ground then carries is what the fingers' share misses, held within the tolerance.)
            self.assertLess(slip, MAX_SLIP)
            self.assertAlmostEqual(carried / weight, 1.0, delta=WEIGHT_TOLERANCE)
        else:
            self.assertGreater(final_drop, MIN_SLIP_OUT, 'the object did not slip out')


if __name__ == '__main__':
    rostest.rosrun(PKG, 'grasp', GraspTest)
