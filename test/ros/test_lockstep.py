#!/usr/bin/env python3
"""Lockstep with a client: flsm_node on ~clock sim, ~start_paused, is stepped through ~step; each
answer comes once the steps are taken, with the time they reached, and the particles published
at that stamp are the same to the bit in two runs of the node. While paused, /clock stands
still; ~step while running is refused with the reason; ~pause and ~unpause switch."""

import os
import signal
import subprocess
import threading
import time
import unittest

import roslib.packages
import rospy
import rostest
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import PointCloud2
from std_srvs.srv import Empty

from deformable_flsm.msg import SimulationState
from deformable_flsm.srv import Step

PKG = 'deformable_flsm'
TIMEOUT_S = 60.0
NODE = 'flsm_lockstep'
DT = 1.0 / 60.0  # ~time_step of config/flsm.yaml
PARAMS = ['_clock:=sim', '_start_paused:=true', '_particle_budget:=400',
          '_ground_clearance:=0.01', '_render_triangle_budget:=2000']


def node_binary():
    found = roslib.packages.find_node(PKG, 'flsm_node')
    if not found:
        raise RuntimeError('flsm_node not built')
    return found[0]


class Run(object):
    """One flsm_node process and the clouds it publishes."""

    def __init__(self):
        self.proc = subprocess.Popen([node_binary(), '__name:=' + NODE] + PARAMS,
                                     stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
        self.lock = threading.Lock()
        self.clouds = {}
        self.states = []
        self.sub = rospy.Subscriber('/%s/particles' % NODE, PointCloud2, self.on_cloud,
                                    queue_size=100)
        self.state_sub = rospy.Subscriber('/%s/state' % NODE, SimulationState,
                                          lambda m: self.states.append(m), queue_size=100)
        rospy.wait_for_service('/%s/step' % NODE, timeout=TIMEOUT_S)
        # connected before the first step: the node sends a topic nobody subscribes to no message,
        # and the paused time brings no second chance
        deadline = time.monotonic() + TIMEOUT_S
        while (self.sub.get_num_connections() == 0 or self.state_sub.get_num_connections() == 0) \
                and time.monotonic() < deadline:
            time.sleep(0.01)
        self.step = rospy.ServiceProxy('/%s/step' % NODE, Step)
        self.pause = rospy.ServiceProxy('/%s/pause' % NODE, Empty)
        self.unpause = rospy.ServiceProxy('/%s/unpause' % NODE, Empty)

    def on_cloud(self, msg):
        with self.lock:
            self.clouds[msg.header.stamp] = bytes(msg.data)

    def cloud_at(self, t):
        """The cloud stamped `t` (s; a stamp is whole nanoseconds, rounded as roscpp rounds)."""
        deadline = time.monotonic() + TIMEOUT_S
        while time.monotonic() < deadline:
            with self.lock:
                for stamp, data in self.clouds.items():
                    if abs(stamp.to_sec() - t) < 1e-6:
                        return data
            time.sleep(0.01)
        raise AssertionError('no ~particles stamped %.9f' % t)

    def state_where(self, condition):
        deadline = time.monotonic() + TIMEOUT_S
        while time.monotonic() < deadline:
            found = [s for s in list(self.states) if condition(s)]
            if found:
                return found[-1]
            time.sleep(0.01)
        raise AssertionError('no ~state as expected')

    def close(self):
        self.sub.unregister()
        self.state_sub.unregister()
        self.proc.send_signal(signal.SIGINT)
        try:
            return self.proc.communicate(timeout=TIMEOUT_S)[0].decode('utf-8', 'replace')
        except subprocess.TimeoutExpired:
            self.proc.kill()
            return self.proc.communicate()[0].decode('utf-8', 'replace')


class LockstepTest(unittest.TestCase):

    def stepped_clouds(self, check):
        run = Run()
        try:
            clouds = []
            time_now = 0.0
            for n in (1, 9, 30, 20):
                r = run.step(n)
                self.assertTrue(r.success, r.message)
                time_now += n * DT
                self.assertAlmostEqual(r.time, time_now, delta=1e-9)
                clouds.append(run.cloud_at(r.time))
            if check:
                self.check_pause_and_refusal(run, time_now)
        finally:
            out = run.close()
        self.assertNotIn('FATAL', out, out)
        return clouds

    def check_pause_and_refusal(self, run, paused_at):
        # Paused: the node serves no later time, however long the client thinks.
        clocks = []
        sub = rospy.Subscriber('/clock', Clock, lambda m: clocks.append(m.clock.to_sec()))
        time.sleep(1.0)
        self.assertTrue(all(c <= paused_at + 1e-9 for c in clocks), clocks)
        run.unpause()
        run.state_where(lambda s: not s.paused)
        time.sleep(0.5)
        sub.unregister()
        self.assertGreater(max(clocks), paused_at + 5 * DT, 'the time did not go on when unpaused')
        r = run.step(1)
        self.assertFalse(r.success)
        self.assertIn('pause it first', r.message)
        run.pause()
        # ~state says so at once, although the paused time moves no timer
        state = run.state_where(lambda s: s.paused and 'not_paused' in s.reject_reasons)
        self.assertTrue(state.paused)

    def test_two_runs_step_to_the_same_particles(self):
        first = self.stepped_clouds(check=True)
        second = self.stepped_clouds(check=False)
        self.assertEqual(len(first), len(second))
        for k, (a, b) in enumerate(zip(first, second)):
            self.assertEqual(a, b, 'the clouds after step call %d differ' % k)
        self.assertNotEqual(first[0], first[-1], 'nothing moved: the test would prove nothing')


if __name__ == '__main__':
    rospy.init_node('test_lockstep')
    rostest.rosrun(PKG, 'lockstep', LockstepTest)
