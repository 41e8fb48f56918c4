#!/usr/bin/env python3
"""measure_node: the figures of flsm_node that docs/performance.md reports, measured on this machine.

    ./scripts/flsm measure [--rviz] [--seconds N] [--params file.yaml] [--scene file.yaml]

Starts a master on its own port and flsm.launch (the default scene unless --params; --scene
loads a file over it, as demo.launch's scenes do: config/implicit.yaml), then:
  1. start-up: the node's own report (lattice, step cost, CPU share it expects);
  2. at rest, with subscribers on ~mesh, ~surface and ~particles (rospy.AnyMsg: the bytes are
     received, not decoded, as RViz or rostopic hz would) -- or RViz itself under Xvfb with
     --rviz: the node's CPU (utime + stime of all its threads, /proc/<pid>/stat);
  3. while flsm_demo drags the ear and pokes the body: the same CPU figure, the rates of every
     topic (mean, and the longest gap), the achieved real-time factor and step time (~state);
  4. drag latency: a hard drag's target is moved; the time until a ~particles message shows the
     particle at the new target (command -> simulation thread -> step -> publish -> receipt),
     and until the stamp of that message (the publish tick, which sends ~mesh first); ~mesh and
     ~surface are read meanwhile by a second process (or RViz);
  5. time to rest: from releasing a drag until ~state says idle.
Everything it starts is stopped by process id at the end.
"""

import argparse
import os
import signal
import subprocess
import sys
import threading
import time
import xmlrpc.client
import yaml

import numpy as np
import roslib.packages
import rosgraph
import rospy
from geometry_msgs.msg import Point
from sensor_msgs import point_cloud2
from sensor_msgs.msg import PointCloud2

from deformable_flsm.msg import DragCommand, SimulationState

# A reader of ~mesh and ~surface in a process of its own (bytes received, not decoded).
SINK = ('import rospy\n'
        'rospy.init_node("measure_sink", anonymous=True)\n'
        'subs = [rospy.Subscriber(t, rospy.AnyMsg, lambda m: None, queue_size=1)\n'
        '        for t in ("/flsm_node/mesh", "/flsm_node/surface")]\n'
        'rospy.spin()\n')
LATENCY_SAMPLES = 40
PORT = 11397
XVFB_DISPLAY = ':97'
TICK = os.sysconf('SC_CLK_TCK')


def cpu_seconds(pid):
    """utime + stime of a process (all threads), in seconds."""
    with open('/proc/%d/stat' % pid) as f:
        fields = f.read().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / float(TICK)


def cpu_share(pid, seconds):
    c0, t0 = cpu_seconds(pid), time.time()
    time.sleep(seconds)
    return (cpu_seconds(pid) - c0) / (time.time() - t0)


def node_pid(name):
    master = rosgraph.Master('/measure_node')
    uri = master.lookupNode(name)
    code, _, pid = xmlrpc.client.ServerProxy(uri).getPid('/measure_node')
    return pid


class RateMeter(object):
    """Receipt times of one topic, bytes not decoded."""

    def __init__(self, topic):
        self.topic = topic
        self.times = []
        self.lock = threading.Lock()
        self.sub = rospy.Subscriber(topic, rospy.AnyMsg, self.on_msg, queue_size=100)

    def on_msg(self, _):
        with self.lock:
            self.times.append(time.time())

    def reset(self):
        with self.lock:
            self.times = []

    def report(self):
        with self.lock:
            t = np.array(self.times)
        if len(t) < 2:
            return '%-22s no messages' % self.topic
        gaps = np.diff(t)
        return '%-22s %6.2f Hz (%d messages, longest gap %.0f ms)' % (
            self.topic, (len(t) - 1) / (t[-1] - t[0]), len(t), 1e3 * gaps.max())


def start(cmd, log, env):
    return subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, env=env,
                            preexec_fn=os.setsid)


def stop(proc):
    if proc and proc.poll() is None:
        os.killpg(proc.pid, signal.SIGINT)
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)


def parse_args():
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--rviz', action='store_true', help='subscribe with RViz under Xvfb')
    parser.add_argument('--seconds', type=float, default=10.0, help='length of each window')
    parser.add_argument('--params', default='', help='YAML parameters (default config)')
    parser.add_argument('--scene', default='', help='YAML parameters loaded over --params')
    args = parser.parse_args()
    for path in (args.params, args.scene):
        if path and 'objects' in (yaml.safe_load(open(path)) or {}):
            sys.exit('measure: %s is a scene of several objects (~objects): measure runs the '
                     'drag latency on ~particles, which such a scene does not publish; its cost is '
                     'in bench_world (--only bin) and its topics are under ~objects/<name>/' % path)
    return args


def launch_node(args, env, logdir, procs):
    """roscore, Xvfb with --rviz, and flsm.launch; returns the path of the node's log."""
    procs.append(start(['roscore', '-p', str(PORT)],
                       open(os.path.join(logdir, 'roscore.log'), 'w'), env))
    time.sleep(3)
    launch = ['roslaunch', 'deformable_flsm', 'flsm.launch']
    if args.params:
        launch.append('params:=' + os.path.abspath(args.params))
    if args.scene:
        launch.append('scene_params:=' + os.path.abspath(args.scene))
    if args.rviz:
        env['DISPLAY'] = XVFB_DISPLAY
        env['LIBGL_ALWAYS_SOFTWARE'] = '1'
        procs.append(start(['Xvfb', XVFB_DISPLAY, '-screen', '0', '1200x846x24',
                            '-nolisten', 'tcp'], subprocess.DEVNULL, env))
        time.sleep(2)
        launch.append('rviz:=true')
    node_log = os.path.join(logdir, 'node.log')
    procs.append(start(['stdbuf', '-oL'] + launch, open(node_log, 'w'), env))
    return node_log


def startup_report(node_log):
    """Waits for ~state; prints the node's start-up report. Returns the latest ~state (a dict
    kept up to date), the node's pid, its time step and publish period."""
    rospy.init_node('measure_node')
    state = {'msg': None}
    rospy.Subscriber('/flsm_node/state', SimulationState,
                     lambda m: state.__setitem__('msg', m), queue_size=1)
    rospy.wait_for_message('/flsm_node/state', SimulationState, timeout=120)
    pid = node_pid('/flsm_node')
    step_length = rospy.get_param('/flsm_node/time_step', 1.0 / 60.0)
    publish_period = 1.0 / rospy.get_param('/flsm_node/publish_rate', 30.0)
    print('== start-up report of flsm_node (pid %d)' % pid)
    with open(node_log) as f:
        for line in f:
            if 'flsm_node' in line or line.startswith(('lattice', 'regions', 'material',
                                                       'step', 'render', 'pinned')):
                print('   ' + line.rstrip()[:200])
    return state, pid, step_length, publish_period


def measure_dragging(args, env, logdir, procs, state, pid, meters, who):
    """The node's CPU and the topics' rates while flsm_demo drags and pokes."""
    # (not rosrun: it also finds the copies under .build/ and asks which one)
    demo_path = roslib.packages.find_node('deformable_flsm', 'flsm_demo')[0]
    demo = start([demo_path],
                 open(os.path.join(logdir, 'demo.log'), 'w'), env)
    procs.append(demo)
    while not (state['msg'] and state['msg'].active_drags > 0):
        time.sleep(0.1)  # the demo has grabbed the ear
    for m in meters:
        m.reset()
    share = cpu_share(pid, args.seconds)
    s = state['msg']
    print('\n== while flsm_demo drags and pokes, subscribed: %s' % who)
    print('   node CPU %.1f %% of a core over %.0f s' % (100 * share, args.seconds))
    for m in meters:
        print('   ' + m.report())
    print('   real-time factor %.3f (asked %.2f), step %.2f ms, %d steps dropped, '
          '%d particles' % (s.real_time_factor, s.requested_real_time_factor,
                            1e3 * s.step_time, s.dropped_steps, s.particles))
    stop(demo)
    procs.remove(demo)


def drag_publisher(p):
    """A function that publishes a drag of particle p (id 'latency') on ~drag, once the node
    has subscribed."""
    pub = rospy.Publisher('/flsm_node/drag', DragCommand, queue_size=10)
    while pub.get_num_connections() == 0:
        time.sleep(0.05)

    def drag(action, target):
        m = DragCommand()
        m.action = action
        m.id = 'latency'
        m.particle = p
        m.target = Point(*target)
        pub.publish(m)
    return drag


def measure_latency(drag, x, p, size, step_length, publish_period):
    """Grabs particle p, moves it LATENCY_SAMPLES times and prints the drag latency."""
    seen = {'t': None, 'goal': None, 'generation': 0}
    lock = threading.Lock()

    def on_cloud(msg):
        with lock:
            goal, generation = seen['goal'], seen['generation']
        if goal is None:
            return
        if isinstance(msg, rospy.AnyMsg):
            # This process already reads the topic as raw bytes (the rate meter); rospy
            # hands every subscriber of the topic that type.
            msg = PointCloud2().deserialize(msg._buff)
        q = next(point_cloud2.read_points(msg, field_names=('x', 'y', 'z'), skip_nans=False,
                                          uvs=[(p, 0)]))
        if np.linalg.norm(np.array(q) - goal) < 1e-4:
            with lock:
                # Only for the goal this callback compared with (not one set meanwhile).
                if seen['t'] is None and seen['generation'] == generation:
                    seen['t'] = time.time()
                    seen['stamp'] = msg.header.stamp.to_sec()

    sub = rospy.Subscriber('/flsm_node/particles', PointCloud2, on_cloud, queue_size=5,
                           buff_size=2 ** 24)
    drag(DragCommand.GRAB, x[p])
    time.sleep(1.0)
    latencies, stamped = [], []
    rng = np.random.default_rng(7)
    for k in range(LATENCY_SAMPLES):
        goal = x[p] + size * 0.05 * np.array([np.cos(k), np.sin(k), 0.3])
        with lock:
            seen['t'] = None
            seen['goal'] = goal
            seen['generation'] = k + 1
        t_sent = time.time()
        drag(DragCommand.MOVE, goal)
        while time.time() - t_sent < 2.0:
            with lock:
                if seen['t'] is not None:
                    break
            time.sleep(0.002)
        with lock:
            if seen['t'] is not None:
                latencies.append(seen['t'] - t_sent)
                stamped.append(seen['stamp'] - t_sent)
        # Commands at phases spread evenly over the publish and step periods: a fixed pause
        # (a multiple of either period) would sample one or two phases only.
        time.sleep(0.3 + rng.uniform(0.0, 0.1))
    lat = np.array(latencies) * 1e3
    pub_lat = np.array(stamped) * 1e3
    print('\n== drag latency (MOVE published -> ~particles shows the particle there), %d of %d'
          % (len(lat), LATENCY_SAMPLES))
    if len(lat):
        print('   received: median %.0f ms, min %.0f ms, max %.0f ms (step %.1f ms of simulated '
              'time, publish period %.1f ms)' % (np.median(lat), lat.min(), lat.max(),
                                                 1e3 * step_length, 1e3 * publish_period))
        # The stamp of ~mesh, ~surface and ~particles is the start of the publish tick that
        # carries the state (the mesh is published first in it): what is left is building,
        # sending and this script's Python receiving.
        print('   published (the tick\'s stamp, ~mesh first): median %.0f ms, min %.0f ms, '
              'max %.0f ms' % (np.median(pub_lat), pub_lat.min(), pub_lat.max()))
    sub.unregister()


def main():
    args = parse_args()
    env = dict(os.environ)
    env['ROS_MASTER_URI'] = 'http://localhost:%d' % PORT
    env['ROS_HOSTNAME'] = 'localhost'
    os.environ.update(env)
    logdir = os.path.join(env.get('ROS_HOME', '/tmp'), 'measure')
    os.makedirs(logdir, exist_ok=True)
    procs = []
    try:
        node_log = launch_node(args, env, logdir, procs)
        state, pid, step_length, publish_period = startup_report(node_log)

        # The rest positions, read before this process subscribes for the rates (rospy shares
        # one connection per topic within a process, so later readers see only new messages).
        cloud = rospy.wait_for_message('/flsm_node/particles', PointCloud2, timeout=30)
        x = np.array(list(point_cloud2.read_points(cloud, field_names=('x', 'y', 'z'))))
        p = int(np.argmax(x[:, 2]))
        size = float(np.linalg.norm(x.max(axis=0) - x.min(axis=0)))

        meters = [] if args.rviz else [RateMeter('/flsm_node/mesh'),
                                       RateMeter('/flsm_node/surface'),
                                       RateMeter('/flsm_node/particles')]
        state_meter = RateMeter('/flsm_node/state')
        who = 'RViz (config/flsm.rviz)' if args.rviz else '~mesh, ~surface, ~particles'

        # -- at rest ---------------------------------------------------------------------
        t0 = time.time()
        while not (state['msg'] and state['msg'].idle) and time.time() - t0 < 120:
            time.sleep(0.2)
        print('\n== at rest (idle %s after %.0f s from start), subscribed: %s'
              % (state['msg'].idle, time.time() - t0, who))
        time.sleep(2.0)
        share = cpu_share(pid, args.seconds)
        print('   node CPU %.2f %% of a core over %.0f s' % (100 * share, args.seconds))

        # -- dragging --------------------------------------------------------------------
        measure_dragging(args, env, logdir, procs, state, pid, meters + [state_meter], who)

        # -- drag latency ----------------------------------------------------------------
        # ~mesh and ~surface keep a reader (the node builds and sends them as before), but in
        # a process of their own: receiving 5 MB messages 30 times a second in this one would
        # delay the probe's callback behind Python's lock and count that as latency.
        if meters:
            for m in meters[:2]:
                m.sub.unregister()
            procs.append(start(['/usr/bin/python3', '-c', SINK], subprocess.DEVNULL, env))
            time.sleep(3.0)
        drag = drag_publisher(p)
        measure_latency(drag, x, p, size, step_length, publish_period)

        # -- time to rest ----------------------------------------------------------------
        drag(DragCommand.MOVE, x[p] + size * np.array([0.2, 0.0, 0.0]))
        time.sleep(2.0)
        drag(DragCommand.RELEASE, x[p])
        t0 = time.time()
        while not (state['msg'].idle and state['msg'].active_drags == 0) and time.time() - t0 < 120:
            time.sleep(0.05)
        print('\n== time to rest after releasing a 20 %% drag of the ear: %.1f s (wall)'
              % (time.time() - t0))
    finally:
        for proc in reversed(procs):
            stop(proc)
    return 0


if __name__ == '__main__':
    sys.exit(main())
