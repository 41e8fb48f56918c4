"""Helpers shared by the rostest nodes of flsm_node: a client that sends commands the way any
other node would (topics and services of /flsm_node) and reads the state back."""

import math
import os
import signal
import subprocess
import threading
import time

import numpy as np
import rospy
from geometry_msgs.msg import Point, Vector3
from sensor_msgs import point_cloud2
from sensor_msgs.msg import PointCloud2
from std_srvs.srv import Trigger

from deformable_flsm.msg import ColliderCommand, DragCommand, ForceCommand, SimulationState
from deformable_flsm.srv import PinBox


def wait_recording(record, topics, timeout=60.0):
    """Until `rosbag record` (subprocess.Popen) subscribes to every topic of `topics` (a busy
    machine takes seconds); an empty string, or why not (it stopped, or it did not in time)."""
    import rosgraph
    master = rosgraph.Master('/flsm_testing')
    deadline = time.time() + timeout
    while time.time() < deadline:
        if record.poll() is not None:
            return 'rosbag record stopped'
        _, subscribers, _ = master.getSystemState()
        subscribed = {t for t, nodes in subscribers if any(n.startswith('/record') for n in nodes)}
        if all(t in subscribed for t in topics):
            time.sleep(0.5)
            return ''
        time.sleep(0.2)
    return 'rosbag record did not subscribe to %s within %.0f s' % (', '.join(topics), timeout)


def stop_recording(record, path, timeout=60.0):
    """Stops `rosbag record` (started as subprocess.Popen) and waits until its bag is closed at
    `path`; False if it was not within `timeout` s. `rosbag record` is a Python wrapper around the
    recorder: on SIGINT it passes the signal on and exits at once, while the recorder still writes
    the bag's index and renames `path`.active to `path` (on a busy machine, seconds later). So
    the wait is for the bag, not for the process."""
    record.send_signal(signal.SIGINT)
    try:
        record.wait(timeout)
    except subprocess.TimeoutExpired:
        record.kill()
    deadline = time.time() + timeout
    while time.time() < deadline:
        if os.path.isfile(path) and not os.path.exists(path + '.active'):
            return True
        time.sleep(0.1)
    return False


class Counter(object):
    """Counts the messages of one topic and keeps the last one."""

    def __init__(self, topic, msg_type):
        self.count = 0
        self.last = None
        self.sub = rospy.Subscriber(topic, msg_type, self.on_msg, queue_size=50)

    def on_msg(self, msg):
        self.last = msg
        self.count += 1

    def close(self):
        self.sub.unregister()


class FlsmClient(object):
    """Talks to one flsm_node. Keeps the latest ~state; reads ~particles on demand."""

    def __init__(self, node='/flsm_node', timeout=60.0):
        self.node = node
        self._lock = threading.Lock()
        self._state = None
        self._state_count = 0
        rospy.Subscriber(node + '/state', SimulationState, self._on_state, queue_size=10)
        self.drag_pub = rospy.Publisher(node + '/drag', DragCommand, queue_size=100)
        self.force_pub = rospy.Publisher(node + '/force', ForceCommand, queue_size=100)
        for srv in ('reset', 'release_all', 'pin_box'):
            rospy.wait_for_service(node + '/' + srv, timeout=timeout)
        self._reset = rospy.ServiceProxy(node + '/reset', Trigger)
        self._release_all = rospy.ServiceProxy(node + '/release_all', Trigger)
        self._pin_box = rospy.ServiceProxy(node + '/pin_box', PinBox)
        self.wait_state(lambda s: True, timeout)
        self._wait_connected(self.drag_pub, timeout)
        self._wait_connected(self.force_pub, timeout)
        rest = self.particles()
        self.rest = rest.copy()
        lo, hi = rest.min(axis=0), rest.max(axis=0)
        self.size = float(np.linalg.norm(hi - lo))  # like Lattice::objectSize()
        self.frame = 'world'

    def collider_publisher(self, queue_size=100, timeout=10.0):
        """A publisher of ColliderCommand on ~collider, once the node has subscribed to it."""
        pub = rospy.Publisher(self.node + '/collider', ColliderCommand, queue_size=queue_size)
        self._wait_connected(pub, timeout)
        return pub

    @staticmethod
    def _wait_connected(pub, timeout):
        end = time.time() + timeout
        while pub.get_num_connections() == 0 and time.time() < end:
            time.sleep(0.05)

    def _on_state(self, msg):
        with self._lock:
            self._state = msg
            self._state_count += 1

    # --- reading ---------------------------------------------------------------------------

    def state(self):
        with self._lock:
            return self._state

    def state_count(self):
        with self._lock:
            return self._state_count

    def wait_state(self, predicate, timeout=10.0):
        """The first ~state for which predicate holds; None after `timeout` seconds."""
        end = time.time() + timeout
        while time.time() < end and not rospy.is_shutdown():
            s = self.state()
            if s is not None and predicate(s):
                return s
            time.sleep(0.02)
        return None

    def particles(self, timeout=10.0, with_displacement=False):
        """#P x 3 particle positions (or #P x 4 with the displacement field) from ~particles."""
        cloud = rospy.wait_for_message(self.node + '/particles', PointCloud2, timeout=timeout)
        fields = ('x', 'y', 'z', 'displacement') if with_displacement else ('x', 'y', 'z')
        return np.array(list(point_cloud2.read_points(cloud, field_names=fields)))

    def wait_particles(self, predicate, timeout=10.0):
        """The first particle array (#P x 3) for which predicate holds, or None."""
        end = time.time() + timeout
        while time.time() < end and not rospy.is_shutdown():
            x = self.particles()
            if predicate(x):
                return x
        return None

    def rejected(self, reason):
        s = self.state()
        return dict(zip(s.reject_reasons, s.reject_counts)).get(reason, 0)

    # --- commands --------------------------------------------------------------------------

    def drag(self, action, drag_id='test', particle=-1, point=(0, 0, 0), count=0,
             target=(0, 0, 0), stiffness=0.0, frame=''):
        m = DragCommand()
        m.header.frame_id = frame
        m.action = action
        m.id = drag_id
        m.particle = particle
        m.point = Point(*point)
        m.count = count
        m.target = Point(*target)
        m.stiffness = stiffness
        self.drag_pub.publish(m)

    def grab(self, particle, target, drag_id='test', stiffness=0.0, frame=''):
        self.drag(DragCommand.GRAB, drag_id, particle=particle, target=target,
                  stiffness=stiffness, frame=frame)

    def move(self, target, drag_id='test', frame=''):
        self.drag(DragCommand.MOVE, drag_id, target=target, frame=frame)

    def release(self, drag_id='test'):
        self.drag(DragCommand.RELEASE, drag_id)

    def force(self, kind, force, particle=-1, point=(0, 0, 0), radius=0.0, duration=0.0,
              frame=''):
        m = ForceCommand()
        m.header.frame_id = frame
        m.kind = kind
        m.particle = particle
        m.point = Point(*point)
        m.radius = radius
        m.force = Vector3(*force)
        m.duration = duration
        self.force_pub.publish(m)

    def reset(self):
        return self._reset()

    def release_all(self):
        return self._release_all()

    def pin_box(self, lo, hi, pin=True):
        return self._pin_box(Point(*lo), Point(*hi), pin)

    def settle(self, timeout=30.0):
        """Releases everything, resets to rest and waits until the node rests (idle)."""
        self.release_all()
        steps = self.state().steps
        self.reset()
        # A ~state sent just before the reset took effect may still say idle: the reset wakes
        # the simulation, which steps at least once before it can rest again.
        if self.wait_state(lambda s: s.steps > steps, timeout) is None:
            return None
        return self.wait_state(lambda s: s.idle and s.active_drags == 0, timeout)


def mouse_feedback(pub, marker, event, pose=(0.0, 0.0, 0.0), point=None):
    """Publishes on `pub` (~drag_marker/feedback) what RViz sends for a mouse event on the handle
    `marker`: the handle moved to `pose`, and the point under the cursor when given."""
    from visualization_msgs.msg import InteractiveMarkerFeedback
    m = InteractiveMarkerFeedback()
    m.header.frame_id = 'world'
    m.header.stamp = rospy.Time.now()
    m.client_id = '/rviz/InteractiveMarkers'
    m.marker_name = marker
    m.control_name = 'drag'
    m.event_type = event
    m.pose.position = Point(*pose)
    m.pose.orientation.w = 1.0
    if point is not None:
        m.mouse_point = Point(*point)
        m.mouse_point_valid = True
    pub.publish(m)


def top_particle(x):
    """Index of the highest particle (the bunny's ear)."""
    return int(np.argmax(x[:, 2]))


def finite(values):
    return all(math.isfinite(v) for v in values)


class ObjectsClient(object):
    """Talks to a flsm_node with ~objects: each object's ~objects/<name>/state, clouds and
    commands, the whole node's ~state and ~contact_wrenches."""

    def __init__(self, names, node='/flsm_node', timeout=60.0):
        from deformable_flsm.msg import ContactWrenches
        self.node = node
        self.names = list(names)
        self._lock = threading.Lock()
        self._states = {}
        self._state = None
        self._wrenches = None
        self._subs = [rospy.Subscriber(node + '/state', SimulationState, self._on_state,
                                       queue_size=10),
                      rospy.Subscriber(node + '/contact_wrenches', ContactWrenches,
                                       self._on_wrenches, queue_size=10)]
        for n in self.names:
            self._subs.append(rospy.Subscriber(self.topic(n, 'state'), SimulationState,
                                               self._on_object_state, callback_args=n,
                                               queue_size=10))
        self.drag_pubs = {n: rospy.Publisher(self.topic(n, 'drag'), DragCommand, queue_size=10)
                          for n in self.names}
        self.force_pubs = {n: rospy.Publisher(self.topic(n, 'force'), ForceCommand, queue_size=10)
                           for n in self.names}
        end = time.time() + timeout
        while time.time() < end and (self.state() is None or
                                     any(self.object_state(n) is None for n in self.names)):
            time.sleep(0.05)
        for pub in list(self.drag_pubs.values()) + list(self.force_pubs.values()):
            FlsmClient._wait_connected(pub, timeout)

    def topic(self, name, leaf):
        return '%s/objects/%s/%s' % (self.node, name, leaf)

    def _on_state(self, msg):
        with self._lock:
            self._state = msg

    def _on_object_state(self, msg, name):
        with self._lock:
            self._states[name] = msg

    def _on_wrenches(self, msg):
        with self._lock:
            self._wrenches = msg

    def state(self):
        with self._lock:
            return self._state

    def object_state(self, name):
        with self._lock:
            return self._states.get(name)

    def wrenches(self):
        with self._lock:
            return self._wrenches

    def wait_sim_time(self, t, timeout, or_idle_after=None):
        """Waits until the simulation has run `t` s; True when it did within `timeout` s. With
        `or_idle_after`, also when it came to rest after that much simulated time (the node no
        longer steps at rest, and its clock stops)."""
        end = time.time() + timeout
        while time.time() < end and not rospy.is_shutdown():
            s = self.state()
            if s is not None and (s.sim_time >= t or (or_idle_after is not None and s.idle and
                                                      s.sim_time > or_idle_after)):
                return True
            time.sleep(0.05)
        return False

    def particles(self, name, timeout=10.0):
        cloud = rospy.wait_for_message(self.topic(name, 'particles'), PointCloud2, timeout=timeout)
        return np.array(list(point_cloud2.read_points(cloud, field_names=('x', 'y', 'z'))))

    def rejected(self, reason):
        s = self.state()
        return dict(zip(s.reject_reasons, s.reject_counts)).get(reason, 0)

    def drag(self, name, action, drag_id='test', particle=-1, point=(0, 0, 0), count=0,
             target=(0, 0, 0)):
        m = DragCommand()
        m.action = action
        m.id = drag_id
        m.particle = particle
        m.point = Point(*point)
        m.count = count
        m.target = Point(*target)
        self.drag_pubs[name].publish(m)

    def pin_box(self, name, lo, hi, pin=True):
        srv = self.topic(name, 'pin_box')
        rospy.wait_for_service(srv, timeout=10.0)
        return rospy.ServiceProxy(srv, PinBox)(Point(*lo), Point(*hi), pin)

    def close(self):
        for s in self._subs:
            s.unregister()


def half_spacing(x):
    """Half the lattice spacing of one object's particles (#P x 3): the median nearest-neighbour
    distance (a cubic grid, barely strained at rest) over two, the default contact radius."""
    d = np.linalg.norm(x[:, None, :] - x[None, :, :], axis=2)
    d[d == 0.0] = np.inf
    return 0.5 * float(np.median(d.min(axis=1)))
