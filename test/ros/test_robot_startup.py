#!/usr/bin/env python3
"""Bad robot descriptions at start-up: a URDF that does not parse, a ~robot_description that
names no parameter, a collision mesh that does not exist stop flsm_node with a fatal message
naming what to fix; a link pattern that matches no link is a warning naming it, and the node
runs on. Runs the node binary against the rostest's master, on a coarse lattice."""

import os
import signal
import subprocess
import unittest

import roslib.packages
import rospy
import rostest

from deformable_flsm.msg import SimulationState

PKG = 'deformable_flsm'
# Generous: the node only has to reach the master, read parameters and fail (or warn).
TIMEOUT_S = 60.0
COARSE = '_particle_budget:=300'

GOOD_URDF = """<?xml version="1.0"?>
<robot name="probe">
  <link name="world"/>
  <link name="probe_tip">
    <collision><geometry><sphere radius="0.01"/></geometry></collision>
  </link>
  <joint name="mount" type="fixed">
    <parent link="world"/><child link="probe_tip"/><origin xyz="0.5 0 0"/>
  </joint>
</robot>
"""

# A <joint> whose child link does not exist: urdfdom refuses the model.
BROKEN_URDF = """<?xml version="1.0"?>
<robot name="broken">
  <link name="base"/>
  <joint name="j" type="fixed"><parent link="base"/><child link="nowhere"/></joint>
</robot>
"""

MISSING_MESH_URDF = """<?xml version="1.0"?>
<robot name="meshy">
  <link name="hand">
    <collision>
      <geometry><mesh filename="package://deformable_flsm/urdf/meshes/no_such_hand.stl"/></geometry>
    </collision>
  </link>
</robot>
"""


def find_node_binary():
    paths = roslib.packages.find_node(PKG, 'flsm_node')
    if not paths:
        raise RuntimeError('flsm_node not found: is the workspace built and sourced?')
    return paths[0]


class RobotStartupTest(unittest.TestCase):

    def run_node(self, name, *params):
        """Runs flsm_node as /<name> until it exits; returns (code, output)."""
        cmd = [find_node_binary(), '__name:=' + name, COARSE] + list(params)
        proc = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                              timeout=TIMEOUT_S, env=dict(os.environ), check=False)
        return proc.returncode, proc.stdout.decode('utf-8', 'replace')

    def assert_fails_naming(self, name, expected, *params):
        code, out = self.run_node(name, *params)
        self.assertNotEqual(code, 0, 'flsm_node exited 0 with %s; output:\n%s' % (params, out))
        self.assertIn('FATAL', out, 'no fatal message; output:\n%s' % out)
        for text in expected:
            self.assertIn(text, out, 'message does not mention %r; output:\n%s' % (text, out))

    def test_urdf_that_does_not_parse_stops_the_node(self):
        rospy.set_param('/broken_description', BROKEN_URDF)
        self.assert_fails_naming('flsm_broken_urdf',
                                 ['~robot_description', '/broken_description', 'does not parse'],
                                 '_robot_description:=broken_description')

    def test_description_parameter_that_is_not_set_stops_the_node(self):
        self.assert_fails_naming('flsm_no_description',
                                 ['~robot_description', '/no_such_description', 'not set'],
                                 '_robot_description:=no_such_description')

    def test_missing_collision_mesh_is_named(self):
        rospy.set_param('/meshy_description', MISSING_MESH_URDF)
        self.assert_fails_naming('flsm_missing_mesh_link',
                                 ["robot link 'hand'", 'no_such_hand.stl',
                                  '~robot_exclude_links'],
                                 '_robot_description:=meshy_description')

    def test_link_pattern_matching_nothing_is_a_warning_naming_it(self):
        rospy.set_param('/probe_description', GOOD_URDF)
        rospy.set_param('/flsm_bad_pattern/robot_links', ['probe_.*', 'gripper_finger_.*'])
        cmd = [find_node_binary(), '__name:=flsm_bad_pattern', COARSE,
               '_robot_description:=probe_description']
        proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                env=dict(os.environ))
        try:
            # Running: it publishes its state; then stopped as Ctrl-C would (its log flushed).
            state = rospy.wait_for_message('/flsm_bad_pattern/state', SimulationState,
                                           timeout=TIMEOUT_S)
            running = proc.poll() is None
        finally:
            proc.send_signal(signal.SIGINT)
            out = proc.communicate(timeout=TIMEOUT_S)[0].decode('utf-8', 'replace')
        self.assertTrue(running, 'the node stopped:\n' + out)
        self.assertEqual(state.solver_resets, 0)
        lines = out.splitlines()
        self.assertIn('1 colliders on 1 links (probe_tip)', out, out)
        warnings = [l for l in lines if 'WARN' in l and 'gripper_finger_' in l]
        self.assertEqual(len(warnings), 1, out)
        self.assertIn("~robot_links pattern 'gripper_finger_.*' matches no link", warnings[0])
        self.assertIn('probe_tip', warnings[0], 'the warning lists the links there are')
        self.assertNotIn("'probe_.*' matches no link", out)
        # a list parameter that is read is not reported as unknown
        self.assertNotIn('not a parameter of flsm_node', out)


if __name__ == '__main__':
    rospy.init_node('test_robot_startup')
    rostest.rosrun(PKG, 'robot_startup', RobotStartupTest)
