"""The soak's monitor side (scripts/soak, the main process): the node's name, the heartbeat and
~state recorder programs it starts beside the node and the arithmetic of their intervals, the
Monitor of the node's topics, the node's process (pid, RSS, alive), the most memory the flood may
make the node hold (memory_bounded), and the JUnit file of the checks. scripts/soak imports it."""

import math
import os
import socket
import threading
import time
import xml.etree.ElementTree as ET

PKG = 'deformable_flsm'
NODE = '/flsm_node'


# The heartbeat process (see the flood): until the time given, sleeps 5 ms at a time and prints,
# as JSON, its longest wait beyond those 5 ms, when that wait began (epoch s), and every wait
# beyond them longer than STALL_S as [begin, end] (epoch s): the machine's stalls. Every 20 ms it
# also reads the node's threads from /proc: their time on a CPU (schedstat, ns) and which are
# runnable (state R). A span of at least UNRUN_S in which a thread of the node was runnable at
# every reading and none of its threads gained a nanosecond on a CPU is a span the kernel did not
# run the node though it could have run: printed as 'unrun' [begin, end] pairs. (With autogroup
# scheduling each session is a group, and the node, in a session of its own, can be left without
# a CPU for seconds while other sessions run, this heartbeat among them.) A thread of the node in
# uninterruptible sleep (state D: waiting on a disk or a page fault) at every reading for at least
# UNRUN_S is printed as 'blocked' [begin, end, thread name, kernel function]: not taken out of the
# gaps (the node answers for what it waits on), but named beside a gap it may explain.
STALL_S = 0.25
UNRUN_S = 0.1
HEARTBEAT = '''
import json, os, sys, time
until, stall, unrun_s, pid = float(sys.argv[1]), float(sys.argv[2]), float(sys.argv[3]), sys.argv[4]
def read(path):
    with open(path) as f:
        return f.read()
def node_threads():
    """{tid: on-CPU ns}, whether any of them is runnable and which are in state D, or None when
    the node is gone."""
    cpu, runnable, waiting = {}, False, set()
    try:
        tids = os.listdir('/proc/%s/task' % pid)
    except OSError:
        return None, False, waiting
    for tid in tids:
        try:
            cpu[tid] = int(read('/proc/%s/task/%s/schedstat' % (pid, tid)).split()[0])
            state = read('/proc/%s/task/%s/stat' % (pid, tid)).rsplit(')', 1)[1].split()[0]
            runnable = runnable or state == 'R'
            if state == 'D':
                waiting.add(tid)
        except (OSError, IndexError, ValueError):
            pass  # a thread that ended meanwhile
    return cpu, runnable, waiting
def waiting_in(tid):
    """The thread's name and the kernel function it sleeps in, read while it waits."""
    name, where = '?', '?'
    try:
        name = read('/proc/%s/task/%s/comm' % (pid, tid)).strip()
        where = read('/proc/%s/task/%s/wchan' % (pid, tid)).strip() or '?'
    except OSError:
        pass
    return name, where
gap, at, last, stalls, unrun, blocked = 0.0, 0.0, time.time(), [], [], []
prev, prev_runnable, since, beats, d_since = None, False, None, 0, {}
while last < until:
    time.sleep(0.005)
    now = time.time()
    if now - last - 0.005 > gap:
        gap, at = now - last - 0.005, last
    if now - last - 0.005 > stall:
        stalls.append([last + 0.005, now])
    last = now
    beats += 1
    if beats % 4:
        continue
    cpu, runnable, waiting = node_threads()
    if cpu is None:
        break
    for tid in list(d_since):
        if tid not in waiting:
            begin, name, where = d_since.pop(tid)
            if now - begin >= unrun_s:
                blocked.append([begin, now, name, where])
    for tid in waiting:
        if tid not in d_since:
            d_since[tid] = (now,) + waiting_in(tid)
    if prev is not None:
        ran = sum(cpu[t] - prev[t] for t in cpu if t in prev)
        if ran == 0 and prev_runnable:
            since = since if since is not None else prev_at
        else:
            if since is not None and prev_at - since >= unrun_s:
                unrun.append([since, prev_at])
            since = None
    prev, prev_runnable, prev_at = cpu, runnable, now
if since is not None and prev_at - since >= unrun_s:
    unrun.append([since, prev_at])
for begin, name, where in d_since.values():
    if last - begin >= unrun_s:
        blocked.append([begin, last, name, where])
print(json.dumps({'gap': gap, 'at': at, 'stalls': stalls, 'unrun': unrun, 'blocked': blocked}))
'''


# The ~state recorder (see the flood): subscribes to ~state with no limit on its queue, so that a
# late read loses no stamp, prints 'ready' at its first message, and when its standard input
# closes prints, as JSON, every (arrival epoch s, header stamp s) and the stalls it looked into.
# A process of its own, which does nothing else (the monitor's threads decode clouds).
# Its watchdog: when no ~state has arrived for WATCH_S (the gap `publishing` fails on), it writes
# what each thread of the node is doing to stall-<k>.txt in the soak's log directory, at most
# WATCH_DUMPS times: first from /proc, which stops nothing (name, state, the kernel function it
# sleeps in, its system call, its kernel stack), then the threads' stacks from gdb when gdb is
# installed (attaching holds the node ~0.5 s, after the gap has already failed the check).
WATCH_S = 1.0
WATCH_DUMPS = 3
STATE_RECORDER = r'''
import json, os, subprocess, sys, threading, time
import rospy
from deformable_flsm.msg import SimulationState
topic, pid, watch_s, dumps_max, log_dir = (sys.argv[1], sys.argv[2], float(sys.argv[3]),
                                          int(sys.argv[4]), sys.argv[5])
lock, seen, stalls = threading.Lock(), [], []
SYSCALLS = {0: 'read', 1: 'write', 7: 'poll', 23: 'select', 35: 'nanosleep', 42: 'connect',
            44: 'sendto', 45: 'recvfrom', 46: 'sendmsg', 47: 'recvmsg', 202: 'futex',
            230: 'clock_nanosleep', 232: 'epoll_wait', 270: 'pselect6', 271: 'ppoll',
            281: 'epoll_pwait', 288: 'accept4'}
def on_state(msg):
    with lock:
        if not seen:
            print('ready', flush=True)
        seen.append((time.time(), msg.header.stamp.to_sec()))
def read(path):
    try:
        with open(path) as f:
            return f.read().strip()
    except OSError:
        return '?'
def threads_now():
    """One line per thread of the node (and its kernel stack), read from /proc."""
    lines, short = [], []
    try:
        tids = sorted(os.listdir('/proc/%s/task' % pid), key=int)
    except OSError:
        return ['the node is gone'], 'the node is gone'
    for tid in tids:
        t = '/proc/%s/task/%s/' % (pid, tid)
        name, state = read(t + 'comm'), read(t + 'stat').rsplit(')', 1)[-1].split()[:1]
        call = read(t + 'syscall').split()
        what = SYSCALLS.get(int(call[0]), 'syscall ' + call[0]) if call and call[0].isdigit() \
            else (call[0] if call else '?')
        wchan = read(t + 'wchan') or '-'
        lines.append('%s %-15s %s %-10s %s' % (tid, name, state[0] if state else '?', what, wchan))
        lines.extend('      ' + k for k in read(t + 'stack').splitlines())
        if name.startswith('flsm_'):  # the node's own threads (roscpp's are in the file)
            short.append('%s %s %s' % (name, state[0] if state else '?', what))
    return lines, ', '.join(short)
def gdb_stacks():
    try:
        out = subprocess.run(['gdb', '-p', pid, '-batch', '-nx', '-ex', 'set pagination off',
                              '-ex', 'thread apply all bt 24'], stdout=subprocess.PIPE,
                             stderr=subprocess.STDOUT, timeout=60).stdout.decode(errors='replace')
        return out
    except (OSError, subprocess.TimeoutExpired) as e:
        return 'no stacks from gdb: %s' % e
def watch():
    while len(stalls) < dumps_max:
        time.sleep(0.05)
        with lock:
            last = seen[-1][0] if seen else None
        if last is None or time.time() - last < watch_s:
            continue
        at = time.time()
        lines, short = threads_now()
        stacks = gdb_stacks()
        path = os.path.join(log_dir, 'stall-%d.txt' % len(stalls))
        with open(path, 'w') as f:
            f.write('no ~state for %.3f s (the last arrived at %.3f, epoch s)\n\n' % (at - last, last))
            f.write('threads of pid %s from /proc (tid, name, state, system call, kernel function; '
                    'kernel stack):\n%s\n\n' % (pid, '\n'.join(lines)))
            f.write('gdb, thread apply all bt:\n%s\n' % stacks)
        stalls.append([last, at, path, short])
        while True:  # one report per stall: wait for ~state again
            time.sleep(0.05)
            with lock:
                if seen[-1][0] > last:
                    break
rospy.init_node('soak_state_recorder', anonymous=True, disable_signals=True)
rospy.Subscriber(topic, SimulationState, on_state, queue_size=None, tcp_nodelay=True)
threading.Thread(target=watch, daemon=True).start()
sys.stdin.read()
with lock:
    print(json.dumps({'seen': seen, 'stalls': list(stalls)}), flush=True)
'''


def union(*lists):
    """The union of lists of [begin, end] intervals, as sorted disjoint intervals."""
    out = []
    for b, e in sorted(i for l in lists for i in l):
        if out and b <= out[-1][1]:
            out[-1][1] = max(out[-1][1], e)
        else:
            out.append([b, e])
    return out


def overlap(a, b, stalls):
    """How long the machine's stalls ([begin, end] pairs) cover of the interval [a, b]."""
    return sum(max(0.0, min(b, e) - max(a, s)) for s, e in stalls)


def free_port():
    with socket.socket() as s:
        s.bind(('localhost', 0))
        return s.getsockname()[1]

class Monitor(object):
    def __init__(self):
        import numpy as np
        import rospy
        from sensor_msgs.msg import PointCloud2
        from deformable_flsm.msg import SimulationState
        self.np = np
        self.lock = threading.Lock()
        self.state = None
        self.states = 0  # ~state messages seen (their stamps: the recorder's, see the flood)
        self.non_finite = []
        self.clouds = {'particles': 0, 'surface': 0}
        self.meshes = 0
        self.largest = {'particles': 0, 'surface': 0, 'mesh': 0}  # serialized bytes
        self.last_particles = None
        rospy.Subscriber(NODE + '/state', SimulationState, self.on_state, queue_size=100)
        rospy.Subscriber(NODE + '/particles', PointCloud2, self.on_cloud, 'particles',
                         queue_size=2, buff_size=2 ** 24)
        rospy.Subscriber(NODE + '/surface', PointCloud2, self.on_cloud, 'surface',
                         queue_size=2, buff_size=2 ** 24)
        rospy.Subscriber(NODE + '/mesh', rospy.AnyMsg, self.on_mesh, queue_size=1,
                         buff_size=2 ** 24)

    def on_state(self, msg):
        values = [msg.sim_time, msg.step_time, msg.real_time_factor, msg.kinetic_energy,
                  msg.max_displacement, msg.max_speed, msg.shape_error, msg.alpha]
        with self.lock:
            self.state = msg
            self.states += 1
            if not all(math.isfinite(v) for v in values):
                self.non_finite.append('~state: %s' % values)

    def on_cloud(self, msg, name):
        np = self.np
        data = np.frombuffer(msg.data, dtype=np.float32)
        finite = bool(np.isfinite(data).all())
        xyz = None
        if name == 'particles':
            xyz = data.reshape(-1, msg.point_step // 4)[:, :3].astype(np.float64)
        with self.lock:
            self.clouds[name] += 1
            self.largest[name] = max(self.largest[name], len(msg.data) + 256)
            if not finite:
                self.non_finite.append('~%s: a non-finite value' % name)
            if xyz is not None:
                self.last_particles = xyz

    def on_mesh(self, msg):
        with self.lock:
            self.meshes += 1
            self.largest['mesh'] = max(self.largest['mesh'], len(msg._buff))

    def latest(self):
        with self.lock:
            return self.state

    def wait_state(self, predicate, timeout):
        end = time.time() + timeout
        while time.time() < end:
            s = self.latest()
            if s is not None and predicate(s):
                return s
            time.sleep(0.05)
        return None

    def rest_particles(self):
        """#P x 3 particle positions of the last ~particles, 1 s after the node said it rests (it
        sends the final state once), or None."""
        time.sleep(1.0)
        with self.lock:
            return self.last_particles


def client_collider_ids(client):
    """The ids of the colliders client number `client` adds, moves and removes."""
    return ['soak%d_%d' % (client, i) for i in range(COLLIDERS_PER_CLIENT)]


def remove_colliders(clients, timeout=10.0):
    """REMOVE of every collider id the clients use (client_collider_ids()); the node refuses
    those it does not have (unknown_collider)."""
    import rospy
    from deformable_flsm.msg import ColliderCommand
    pub = rospy.Publisher(NODE + '/collider', ColliderCommand, queue_size=100)
    end = time.time() + timeout
    while pub.get_num_connections() == 0 and time.time() < end:
        time.sleep(0.05)
    for k in range(clients):
        for collider_id in client_collider_ids(k):
            m = ColliderCommand()
            m.action = ColliderCommand.REMOVE
            m.id = collider_id
            pub.publish(m)
    time.sleep(0.5)  # the queue's thread writes them out
    pub.unregister()


def find_node_pid(launch_pid, timeout=60.0):
    """The pid of flsm_node started by roslaunch `launch_pid`."""
    end = time.time() + timeout
    while time.time() < end:
        for entry in os.listdir('/proc'):
            if not entry.isdigit():
                continue
            try:
                with open('/proc/%s/cmdline' % entry, 'rb') as f:
                    cmd = f.read().split(b'\0')
                with open('/proc/%s/stat' % entry) as f:
                    ppid = int(f.read().rsplit(')', 1)[1].split()[1])
            except (OSError, IndexError, ValueError):
                continue
            if ppid == launch_pid and cmd and cmd[0].endswith(b'/flsm_node'):
                return int(entry)
        time.sleep(0.2)
    return None


def rss_kb(pid):
    try:
        with open('/proc/%d/status' % pid) as f:
            for line in f:
                if line.startswith('VmRSS:'):
                    return int(line.split()[1])
    except OSError:
        return None
    return None


def alive(pid):
    try:
        with open('/proc/%d/stat' % pid) as f:
            return f.read().rsplit(')', 1)[1].split()[0] not in ('Z', 'X')
    except OSError:
        return False


def write_junit(path, results, seconds):
    suite = ET.Element('testsuite', name='soak', tests=str(len(results)),
                       failures=str(sum(1 for r in results if not r[1])), time='%.1f' % seconds)
    for name, ok, detail in results:
        case = ET.SubElement(suite, 'testcase', classname='soak', name=name)
        if ok:
            ET.SubElement(case, 'system-out').text = detail
        else:
            ET.SubElement(case, 'failure', message=detail).text = detail
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    ET.ElementTree(suite).write(path, encoding='utf-8', xml_declaration=True)


# What the node may hold at once, beyond its memory at rest, while clients flood it (B):
# roscpp's queues of ~drag and ~force (1000 each, src/ros/simulator_node.cpp) and ~collider (100,
# src/ros/collider_topics.cpp), the simulation's queue and the batch it applies (256 each,
# CommandLimits::kQueueCapacity).
QUEUED_COMMANDS = 1000 + 1000 + 100 + 2 * 256
# The bound of a heavy topic's messages in roscpp's publish queue, which has no bound of its own:
# the node skips a tick while the queue holds PublishQueueBound::kTicks ticks of them.
BOUND_HEADER = os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir, 'include',
                            'deformable_flsm', 'ros', 'publish_queue_bound.h')


def publish_queue_ticks():
    """PublishQueueBound::kTicks, read from its header so that the bound has one copy."""
    import re
    with open(BOUND_HEADER) as f:
        found = re.search(r'kTicks\s*=\s*(\d+)\s*;', f.read())
    if not found:
        raise RuntimeError('no kTicks in %s: the soak cannot bound ~mesh\'s memory' % BOUND_HEADER)
    return int(found.group(1))


def heavy_copies():
    """Serialized copies of one heavy topic's message the node may hold at once with one
    subscriber: the ticks in roscpp's publish queue, one in the subscriber's outgoing queue of
    the advertised size 1, and one being written to it."""
    return publish_queue_ticks() + 1 + 1


# A queued message: its serialized bytes and its deserialized copy, and the queue's and the
# allocator's bookkeeping.
MESSAGE_OVERHEAD = 1024
# Collider ids per client (client_collider_ids()), and the nodes of a mesh collider's
# distance field (MeshDistanceField::kDefaultResolution 48 along the longest axis, 3 padding
# cells a side, one more node than cells) at 8 B each, and 4 B each while it is built.
COLLIDERS_PER_CLIENT = 3
MESH_FIELD_BYTES = 12 * (48 + 2 * 3 + 1) ** 3
# Free memory glibc keeps per arena with flsm_node's fixed thresholds (src/flsm_node.cpp: trim
# at 1 MiB, plus the default top pad of 128 KiB), for at most 8 arenas per core (mallopt(3)).
ARENA_KEPT = 1024 * 1024 + 128 * 1024
ARENAS = 8 * (os.cpu_count() or 1)


def largest_command_bytes(size):
    """Serialized size of the largest command message the clients send (B)."""
    import io
    from geometry_msgs.msg import Point
    from deformable_flsm.msg import ColliderCommand, DragCommand, ForceCommand
    longest_id = 'x' * 100
    longest_frame = 'no/such/frame'
    c = ColliderCommand()
    c.header.frame_id = longest_frame
    c.id = longest_id
    c.type = 'capsule'
    c.follow_frame = longest_frame
    c.mesh = '/usr/share/glmark2/models/cube.3ds'
    d = DragCommand()
    d.header.frame_id = longest_frame
    d.id = longest_id
    d.point = d.target = Point(size, size, size)
    f = ForceCommand()
    f.header.frame_id = longest_frame
    largest = 0
    for m in (c, d, f):
        buf = io.BytesIO()
        m.serialize(buf)
        largest = max(largest, len(buf.getvalue()))
    return largest


def memory_bound(rss_rest_bytes, clients, command_bytes, state_bytes):
    """The most the node may hold during the flood (B) and its terms, for memory_bounded."""
    terms = [('at rest', rss_rest_bytes),
             ('queued commands', QUEUED_COMMANDS * (2 * command_bytes + MESSAGE_OVERHEAD)),
             ('mesh colliders', clients * COLLIDERS_PER_CLIENT * MESH_FIELD_BYTES),
             ('state messages', heavy_copies() * state_bytes),
             ('allocator', ARENAS * ARENA_KEPT)]
    return sum(t[1] for t in terms), terms


def counted(state):
    return state.accepted_commands + state.rejected_commands
