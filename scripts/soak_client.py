"""A client of the soak (scripts/soak): a process of its own (`scripts/soak --client K`) that
floods the node with drag, force and collider messages, most of them invalid, calls its services
and (client 0) reconfigures it. scripts/soak imports it."""

import json
import os
import random
import sys
import threading
import time

from soak_monitor import NODE, client_collider_ids

# Clients (each in its own process, `--client K`)

NAN, INF = float('nan'), float('inf')


def pick(rng, good, bad, p_bad):
    return rng.choice(bad) if rng.random() < p_bad else rng.choice(good)


def random_point(rng, scale, p_bad):
    bad = [(NAN, 0.0, 0.0), (INF, 0.0, 0.0), (0.0, -INF, 0.0), (1e30, 0.0, 0.0),
           (5.0 * scale, 0.0, 0.0), (0.0, 0.0, -1e9)]
    if rng.random() < p_bad:
        return rng.choice(bad)
    return tuple(rng.uniform(-0.6, 0.6) * scale for _ in range(3))


def count_own_queue_drops():
    """Counts the messages rospy's publisher queues drop in this process: a full queue
    (queue_size) drops its oldest message without a word. Returns {'queue_full': n}, kept up to
    date. rospy's QueuedConnection.write_data, with the count added."""
    from rospy.impl import tcpros_pubsub
    counts = {'queue_full': 0}

    def write_data(self, data):
        with self._lock:
            if self._error:
                error = self._error
                self._error = None
                raise error
            if self._queue_size > 0 and len(self._queue) == self._queue_size:
                del self._queue[0]
                counts['queue_full'] += 1
            self._queue.append(data)
            self._cond_data_available.notify()
        time.sleep(0)
        return True

    tcpros_pubsub.QueuedConnection.write_data = write_data
    return counts


def queued_messages(pubs):
    """Messages still waiting in the publishers' queues of this process."""
    n = 0
    for pub in pubs:
        for c in list(pub.impl.connections):
            n += len(getattr(c, '_queue', ()))
    return n


def call_services(args, scale, p_bad, sent, lock, services, reconf):
    """Service calls and reconfigures, in their own thread: a slow answer must not slow the
    flood of messages."""
    import rospy
    from geometry_msgs.msg import Point

    reset, release_all, pin_box = services
    srng = random.Random(args.seed + 1000)
    next_service = time.time() + srng.uniform(0.0, 0.3)
    next_reconf = time.time() + 0.5
    while time.time() < args.until:
        time.sleep(0.02)
        now = time.time()
        if now >= next_service:
            next_service = now + srng.uniform(0.1, 0.5)
            try:
                r = srng.random()
                if r < 0.2:
                    reset()
                elif r < 0.5:
                    release_all()
                else:
                    lo = random_point(srng, scale, p_bad * 0.3)
                    hi = random_point(srng, scale, p_bad * 0.3)
                    pin_box(Point(*lo), Point(*hi), srng.random() < 0.5)
                with lock:
                    sent['services'] += 1
            except (rospy.ServiceException, rospy.ROSException) as e:
                print('client %d: service call failed: %s' % (args.client, e),
                      file=sys.stderr)
        if reconf is not None and now >= next_reconf:
            next_reconf = now + srng.uniform(0.3, 1.0)
            good = {'youngs_modulus': srng.uniform(2e3, 3e4),
                    'stiffness': srng.uniform(0.2, 1.0), 'damping': srng.uniform(0.0, 30.0),
                    'ambient_damping': srng.uniform(0.0, 3.0),
                    'gravity_z': srng.uniform(-20.0, 5.0)}
            bad = {'youngs_modulus': [-5.0, NAN, 1e12], 'stiffness': [0.0, 2.0, NAN],
                   'damping': [-1.0, INF], 'ambient_damping': [NAN, -3.0],
                   'gravity_z': [NAN, 1e9]}
            key = srng.choice(sorted(good))
            value = srng.choice(bad[key]) if srng.random() < 0.6 else good[key]
            try:
                reconf.update_configuration({key: value})
                with lock:
                    sent['reconfigures'] += 1
            except Exception as e:  # the client raises on a timeout; the node lives on
                print('client %d: reconfigure %s=%r failed: %s' % (args.client, key, value,
                                                                   e), file=sys.stderr)


def collider_command(rng, scale, frames, bad_frames, collider_ids, bad_ids):
    """A collider ADD, MOVE or REMOVE of this client's own ids (never the scene's ground),
    most of them invalid: NaN and infinite poses, a zero quaternion, unknown types and
    frames, negative sizes and friction, missing meshes, ids too long."""
    from geometry_msgs.msg import Point, Quaternion, Vector3
    from deformable_flsm.msg import ColliderCommand

    good_meshes = ['/usr/share/glmark2/models/cube.3ds']
    bad_meshes = ['', '/no/such/mesh.obj', '/etc/hostname']
    m = ColliderCommand()
    m.header.frame_id = pick(rng, frames, bad_frames, 0.3)
    m.action = pick(rng, [0, 0, 1, 1, 2], [3, 200], 0.1)
    m.id = pick(rng, collider_ids, bad_ids, 0.1)
    m.type = pick(rng, ['box', 'sphere', 'capsule', 'plane', 'mesh'],
                  ['', 'cylinder', 'BOX'], 0.15)
    m.pose.position = Point(*random_point(rng, scale, 0.2))
    q = pick(rng, [(0.0, 0.0, 0.0, 1.0), (0.0, 0.3826834, 0.0, 0.9238795)],
             [(0.0, 0.0, 0.0, 0.0), (NAN, 0.0, 0.0, 1.0), (0.0, INF, 0.0, 1.0)], 0.15)
    m.pose.orientation = Quaternion(*q)
    m.follow_frame = pick(rng, [''] * 6 + ['world'], bad_frames, 0.1)
    m.velocity.linear = Vector3(*[pick(rng, [rng.uniform(-0.2, 0.2)], [NAN, INF], 0.1)
                                  for _ in range(3)])
    m.size = Vector3(*[pick(rng, [rng.uniform(0.02, 0.3) * scale], [-1.0, 0.0, NAN, 1e9],
                            0.1) for _ in range(3)])
    m.radius = pick(rng, [rng.uniform(0.02, 0.2) * scale], [-1.0, 0.0, NAN, 1e9], 0.15)
    m.length = pick(rng, [rng.uniform(0.0, 0.3) * scale], [-1.0, NAN], 0.1)
    m.mesh = pick(rng, good_meshes, bad_meshes, 0.3)
    m.mesh_scale = pick(rng, [0.02, 0.05], [0.0, -1.0, NAN], 0.1)
    m.static_friction = pick(rng, [0.0, 0.5, 1.0], [-1.0, NAN, INF], 0.1)
    m.kinetic_friction = pick(rng, [0.0, 0.3], [-0.5, NAN], 0.1)
    return m


def send_flood(args, rng, scale, pubs, sent, lock):
    """Drag, force and collider messages at args.rate until args.until, most of them invalid."""
    from geometry_msgs.msg import Point, Vector3
    from deformable_flsm.msg import DragCommand, ForceCommand

    drag_pub, force_pub, collider_pub = pubs
    frames = ['', 'world', 'flsm_object']
    bad_frames = ['nowhere_%d' % args.client, 'no/such/frame', ' ']
    ids = ['c%d_%d' % (args.client, i) for i in range(4)]
    bad_ids = ['', 'x' * 100, 'tab\tid']
    collider_ids = client_collider_ids(args.client)
    period = 1.0 / args.rate
    t = time.time()
    while t < args.until:
        r = rng.random()
        if r < 0.1:
            collider_pub.publish(collider_command(rng, scale, frames, bad_frames, collider_ids,
                                                  bad_ids))
            with lock:
                sent['collider'] += 1
        elif r < 0.6:
            m = DragCommand()
            m.header.frame_id = pick(rng, frames, bad_frames, 0.3)
            m.action = pick(rng, [0, 1, 2], [3, 7, 255], 0.1)
            m.id = pick(rng, ids, bad_ids, 0.1)
            m.particle = pick(rng, [-1, -1, rng.randrange(0, 3000)], [-2, 10 ** 7, -10 ** 9], 0.2)
            m.point = Point(*random_point(rng, scale, 0.2))
            m.count = pick(rng, [0, 1, 7, 20], [600, 10 ** 6], 0.1)
            m.target = Point(*random_point(rng, scale, 0.3))
            m.stiffness = pick(rng, [0.0, 0.0, 50.0], [-1.0, NAN, 1e12, INF], 0.15)
            drag_pub.publish(m)
            with lock:
                sent['drag'] += 1
        else:
            m = ForceCommand()
            m.header.frame_id = pick(rng, frames, bad_frames, 0.3)
            m.kind = pick(rng, [0, 1], [2, 9], 0.1)
            m.particle = pick(rng, [-1, rng.randrange(0, 3000)], [-7, 10 ** 8], 0.2)
            m.point = Point(*random_point(rng, scale, 0.2))
            m.radius = pick(rng, [0.0, 0.05 * scale, 0.2 * scale], [-1.0, NAN, 10 * scale], 0.2)
            m.force = Vector3(*[pick(rng, [rng.uniform(-0.5, 0.5)], [NAN, 1e6, -INF], 0.2)
                                for _ in range(3)])
            m.duration = pick(rng, [0.1, 0.5], [0.0, -1.0, 1e6, NAN], 0.2)
            force_pub.publish(m)
            with lock:
                sent['force'] += 1
        t += period
        delay = t - time.time()
        if delay > 0:
            time.sleep(delay)
        else:
            t = time.time()  # behind: do not burst to catch up


def finish(args, pubs, sent, dropped):
    """Removes this client's colliders, lets the publisher queues drain, prints what was sent
    (JSON) and ends the process."""
    from deformable_flsm.msg import ColliderCommand

    collider_pub = pubs[2]
    # leave the scene as it was: the node's rest is checked after
    for cid in client_collider_ids(args.client):
        m = ColliderCommand()
        m.action = ColliderCommand.REMOVE
        m.id = cid
        collider_pub.publish(m)
        sent['collider'] += 1
    # Let the last messages leave the publisher queues (the process ends without rospy's
    # shutdown): on a busy machine their threads lag the flood by up to a queue's worth.
    end = time.time() + 30.0
    while queued_messages(pubs) and time.time() < end:
        time.sleep(0.05)
    time.sleep(0.2)  # the last batch, taken off the queue, is being written
    sent['dropped_queue_full'] = dropped['queue_full']
    sent['dropped_at_exit'] = queued_messages(pubs)
    print(json.dumps(sent))
    sys.stdout.flush()
    os._exit(0)  # rospy's shutdown hooks may wait on the master; the result is out


def run_client(args):
    import rospy
    import dynamic_reconfigure.client
    from std_srvs.srv import Trigger
    from deformable_flsm.msg import ColliderCommand, DragCommand, ForceCommand
    from deformable_flsm.srv import PinBox

    rng = random.Random(args.seed)
    dropped = count_own_queue_drops()
    rospy.init_node('soak_client_%d' % args.client, disable_signals=True)
    drag_pub = rospy.Publisher(NODE + '/drag', DragCommand, queue_size=1000)
    force_pub = rospy.Publisher(NODE + '/force', ForceCommand, queue_size=1000)
    collider_pub = rospy.Publisher(NODE + '/collider', ColliderCommand, queue_size=1000)
    for name in ('reset', 'release_all', 'pin_box'):
        rospy.wait_for_service(NODE + '/' + name, timeout=60)
    reset = rospy.ServiceProxy(NODE + '/reset', Trigger)
    release_all = rospy.ServiceProxy(NODE + '/release_all', Trigger)
    pin_box = rospy.ServiceProxy(NODE + '/pin_box', PinBox)
    reconf = None
    if args.client == 0:
        reconf = dynamic_reconfigure.client.Client(NODE, timeout=60)
    end = time.time() + 30.0
    while (drag_pub.get_num_connections() == 0 or force_pub.get_num_connections() == 0
           or collider_pub.get_num_connections() == 0) and time.time() < end:
        time.sleep(0.05)

    scale = args.size
    p_bad = 0.8
    sent = {'drag': 0, 'force': 0, 'collider': 0, 'services': 0, 'reconfigures': 0}
    lock = threading.Lock()
    pubs = (drag_pub, force_pub, collider_pub)
    service_thread = threading.Thread(target=call_services,
                                      args=(args, scale, p_bad, sent, lock,
                                            (reset, release_all, pin_box), reconf))
    service_thread.start()
    send_flood(args, rng, scale, pubs, sent, lock)
    service_thread.join()
    finish(args, pubs, sent, dropped)
