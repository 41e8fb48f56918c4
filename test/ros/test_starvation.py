#!/usr/bin/env python3
"""A good client moves a drag at 50 Hz while a bad one, another process, sends drags at 200 Hz
in a tf frame that nobody publishes. The node must refuse the bad ones without holding up the
good ones: >= 99 % of the good client's commands accepted, and every bad command counted as
`unknown_frame`, none lost."""

import subprocess
import sys
import time
import unittest

import numpy as np
import rospy
import rostest
from geometry_msgs.msg import Point

from deformable_flsm.msg import DragCommand
from flsm_testing import FlsmClient, top_particle

PKG = 'deformable_flsm'
SECONDS = 10.0
GOOD_HZ = 50.0
BAD_HZ = 200.0


def paced(hz, seconds, send):
    """Calls send() at `hz` for `seconds` (a fixed schedule: no drift); returns the count."""
    n = int(round(hz * seconds)) + 1
    t0 = time.time()
    for i in range(n):
        delay = t0 + i / hz - time.time()
        if delay > 0:
            time.sleep(delay)
        send(i)
    return n


def bad_client():
    """The bad client's process: prints 'ready', then the number of commands it sent."""
    rospy.init_node('bad_client', disable_signals=True)
    pub = rospy.Publisher('/flsm_node/drag', DragCommand, queue_size=5000)
    while pub.get_num_connections() == 0:
        time.sleep(0.05)
    time.sleep(0.5)
    print('ready')
    sys.stdout.flush()
    sys.stdin.readline()  # go

    def send(i):
        m = DragCommand()
        m.header.frame_id = 'nowhere'
        m.action = DragCommand.GRAB
        m.id = 'bad%d' % (i % 8)
        m.particle = 0
        pub.publish(m)

    n = paced(BAD_HZ, SECONDS, send)
    time.sleep(1.0)  # let the queue drain before the process goes
    print(n)
    sys.stdout.flush()


class StarvationTest(unittest.TestCase):

    def test_bad_frame_flood_does_not_starve_a_good_client(self):
        rospy.init_node('test_starvation')
        f = FlsmClient()
        self.assertIsNotNone(f.settle(), 'the node did not come to rest')
        x = f.particles()
        p = top_particle(x)
        f.grab(p, tuple(x[p]), drag_id='good')
        self.assertIsNotNone(f.wait_state(lambda s: s.active_drags == 1, 5.0), 'grab refused')

        bad = subprocess.Popen([sys.executable, __file__, '--bad'], stdin=subprocess.PIPE,
                               stdout=subprocess.PIPE)
        self.assertEqual(bad.stdout.readline().strip(), b'ready')
        time.sleep(0.5)
        before = f.state()
        unknown_before = f.rejected('unknown_frame')
        bad.stdin.write(b'go\n')
        bad.stdin.flush()

        amplitude = 0.05 * f.size

        def move(i):
            phase = 2.0 * np.pi * i / GOOD_HZ
            target = x[p] + amplitude * np.array([np.cos(phase) - 1.0, np.sin(phase), 0.0])
            f.move(tuple(target), drag_id='good')

        good_sent = paced(GOOD_HZ, SECONDS, move)
        bad_sent = int(bad.communicate(timeout=60)[0].split()[-1])
        time.sleep(1.0)
        after = f.state()
        accepted = after.accepted_commands - before.accepted_commands
        unknown = f.rejected('unknown_frame') - unknown_before
        rejected = after.rejected_commands - before.rejected_commands
        rospy.loginfo('good client: %d sent, %d accepted; bad client: %d sent, %d counted '
                      'unknown_frame; rejected in all %d', good_sent, accepted, bad_sent,
                      unknown, rejected)
        self.assertGreaterEqual(accepted, 0.99 * good_sent,
                                '%d of the good client\'s %d commands accepted'
                                % (accepted, good_sent))
        self.assertEqual(unknown, bad_sent, 'the bad client sent %d, %d counted unknown_frame'
                         % (bad_sent, unknown))
        self.assertEqual(rejected, bad_sent, 'rejections other than the bad client\'s: %s'
                         % dict(zip(after.reject_reasons, after.reject_counts)))
        f.release('good')


if __name__ == '__main__':
    if '--bad' in sys.argv:
        bad_client()
    else:
        rostest.rosrun(PKG, 'starvation', StarvationTest)
