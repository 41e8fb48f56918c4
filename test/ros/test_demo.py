#!/usr/bin/env python3
"""flsm_demo (launch/demo.launch) drives flsm_node through its public interface: within one
short loop it must have dragged and pushed, with every command accepted."""

import time
import unittest

import rospy
import rostest

from deformable_flsm.msg import SimulationState

PKG = 'deformable_flsm'


class DemoTest(unittest.TestCase):

    def test_demo_drags_and_pushes_without_rejections(self):
        rospy.init_node('test_demo')
        seen = {'drag': False, 'force': False, 'last': None}

        def on_state(s):
            seen['drag'] = seen['drag'] or s.active_drags > 0
            seen['force'] = seen['force'] or s.active_forces > 0
            seen['last'] = s

        rospy.Subscriber('/flsm_node/state', SimulationState, on_state, queue_size=10)
        end = time.time() + 60.0
        while time.time() < end and not (seen['drag'] and seen['force']):
            time.sleep(0.1)
        s = seen['last']
        self.assertIsNotNone(s, 'no ~state')
        self.assertTrue(seen['drag'], 'the demo never dragged')
        self.assertTrue(seen['force'], 'the demo never pushed')
        self.assertGreater(s.accepted_commands, 10)
        self.assertEqual(s.rejected_commands, 0, 'rejected: %s' % s.last_rejection)


if __name__ == '__main__':
    rostest.rosrun(PKG, 'demo', DemoTest)
