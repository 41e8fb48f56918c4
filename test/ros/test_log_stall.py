#!/usr/bin/env python3
"""A held log write holds no thread that simulates or publishes (log_stall.test).

Starts flsm_node itself (the parameters are on the server already) with its stdout and stderr
on a pipe, reads it until the object rests, then shrinks the pipe to a page, fills it from this
side and stops reading for HOLD seconds: every log write of the node now blocks, as it does on
a disk that stalls. Meanwhile a drag moves the object (so that each ~state carries a newly
computed state, stamped with the time it was computed) and commands that the node refuses (and
logs) keep coming. The ~state stamps must advance without a gap over MAX_GAP, and the steps with
them; afterwards the pipe is read again and the node still runs."""

import errno
import fcntl
import math
import os
import select
import subprocess
import threading
import time
import unittest

import roslib.packages
import rospy
import rostest

from deformable_flsm.msg import DragCommand, SimulationState
from flsm_testing import FlsmClient

PKG = 'deformable_flsm'
HOLD = 6.0       # s the pipe stays full
MAX_GAP = 1.0    # s between two ~state stamps while it does (the soak's bound)
F_SETPIPE_SZ = 1031


class LogStallTest(unittest.TestCase):

    @classmethod
    def setUpClass(cls):
        rospy.init_node('test_log_stall')
        node = roslib.packages.find_node(PKG, 'flsm_node')[0]
        rospy.loginfo('log_stall: %s', node)
        cls.node = subprocess.Popen([node, '__name:=flsm_node'], stdout=subprocess.PIPE,
                                    stderr=subprocess.STDOUT)
        cls.reading = threading.Event()
        cls.reading.set()
        cls.paused = threading.Event()
        threading.Thread(target=cls.read, daemon=True).start()
        cls.states = []
        cls.sub = rospy.Subscriber('/flsm_node/state', SimulationState, cls.on_state, queue_size=100)
        cls.flsm = FlsmClient()

    @classmethod
    def tearDownClass(cls):
        cls.reading.set()
        cls.node.terminate()
        cls.node.wait(10.0)

    @classmethod
    def read(cls):
        """Reads the node's output while `reading` is set; says when it has stopped (`paused`)."""
        fd = cls.node.stdout.fileno()
        while True:
            if not cls.reading.is_set():
                cls.paused.set()
                cls.reading.wait()
                cls.paused.clear()
            ready, _, _ = select.select([fd], [], [], 0.1)
            if ready and not os.read(fd, 65536):
                return

    @classmethod
    def on_state(cls, m):
        cls.states.append((time.time(), m.header.stamp.to_sec(), m.steps, m.idle))

    def hold_the_pipe(self):
        """Stops reading the node's stdout and fills the pipe: its next write blocks."""
        self.reading.clear()
        self.assertTrue(self.paused.wait(5.0), 'the reader did not stop')
        fcntl.fcntl(self.node.stdout.fileno(), F_SETPIPE_SZ, 4096)
        w = os.open('/proc/%d/fd/1' % self.node.pid, os.O_WRONLY | os.O_NONBLOCK)
        try:
            for chunk in (512, 1):  # to the last byte: any write of the node's now blocks
                try:
                    while True:
                        os.write(w, b'-' * chunk)
                except OSError as e:
                    self.assertEqual(e.errno, errno.EAGAIN)
        finally:
            os.close(w)

    def pipe_full(self):
        """Whether a write of one byte to the node's stdout pipe would block."""
        w = os.open('/proc/%d/fd/1' % self.node.pid, os.O_WRONLY | os.O_NONBLOCK)
        try:
            os.write(w, b'-')
            return False
        except OSError as e:
            return e.errno == errno.EAGAIN
        finally:
            os.close(w)

    def test_state_keeps_coming_while_the_log_is_held(self):
        f = self.flsm
        self.assertIsNotNone(f.wait_state(lambda s: s.idle, 120.0), 'the object did not rest')
        # the particles at the bunny's head (its base is pinned), pulled round a small circle
        f.drag(DragCommand.GRAB, 'wiggle', point=(0.0, 0.0, 0.08), count=10, target=(0.0, 0.0, 0.08))
        stop = threading.Event()

        def wiggle():
            k = 0
            while not stop.is_set():
                k += 1
                f.move((0.02 * math.sin(0.3 * k), 0.0, 0.08 + 0.02 * math.cos(0.3 * k)), drag_id='wiggle')
                time.sleep(0.05)
        mover = threading.Thread(target=wiggle, daemon=True)
        mover.start()
        time.sleep(2.0)
        self.hold_the_pipe()
        t0 = time.time()
        while time.time() < t0 + HOLD:
            f.drag(DragCommand.GRAB, 'refused', particle=-7, target=(0, 0, 0))  # no such particle
            time.sleep(0.02)
        t1 = time.time()
        self.assertTrue(self.pipe_full(), 'the pipe was not held full: the test held nothing')
        self.reading.set()
        time.sleep(2.0)
        stop.set()
        mover.join()
        s = f.state()
        self.assertGreater(s.rejected_commands, 0)
        held = [x for x in self.states if t0 <= x[0] <= t1]
        around = [x for x in self.states if t0 - 0.5 <= x[0] <= t1 + 0.5]
        gaps = [b[1] - a[1] for a, b in zip(around, around[1:])]
        k = max(range(len(gaps)), key=lambda i: gaps[i])
        rospy.loginfo('log_stall: %d ~state in the %.0f s hold, steps %d -> %d, longest stamp gap %.3f s '
                      '(between states of steps %d and %d, arriving %.3f s apart)',
                      len(held), HOLD, held[0][2], held[-1][2], gaps[k], around[k][2], around[k + 1][2],
                      around[k + 1][0] - around[k][0])
        self.assertFalse(any(x[3] for x in held), 'the object rested: the stamps tell nothing')
        self.assertGreater(held[-1][2] - held[0][2], 0.5 * HOLD * 30, 'the steps stopped')
        self.assertLess(max(gaps), MAX_GAP)
        self.assertIsNone(self.node.poll(), 'the node stopped')


if __name__ == '__main__':
    rostest.rosrun(PKG, 'log_stall', LogStallTest)
