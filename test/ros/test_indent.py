#!/usr/bin/env python3
"""The material under a finger through the node: a frictionless sphere, then a flat punch, sent
on ~collider and pressed 2 mm into the top of a block held by its base; the force on
~contact_wrenches against Hertz's on a layer bonded to its base (the sphere) and against the FEM
oracle's on the same block (the punch: punch_oracle.csv, written by the benchmarks' program

  fem_recording --mesh test/ros/block.obj --spacing 0.0025 --youngs 20000 --nu 0.3 --depth 0.002
                --punch-cells 7 --rate 10 --press 1 --hold 0.5 --noise 0 --subdivision 2 \
                > test/ros/punch_oracle.csv

a linear hexahedral FEM, two elements per lattice cell edge, the punch's nodes prescribed)
(indent.test)."""

import csv
import math
import os
import time
import unittest

import numpy as np
import rospy
import rostest
from geometry_msgs.msg import Point, Quaternion

from deformable_flsm.analytic import hertz_on_bonded_layer
from deformable_flsm.msg import ColliderCommand, ContactWrenches
from flsm_testing import FlsmClient

PKG = 'deformable_flsm'
E, NU = 20000.0, 0.3      # indent.test
SPACING = 0.0025
TOP = 0.03                # the block's top face (m)
RADIUS = 0.02
DEPTH = 0.002
PUNCH_CELLS = 7           # punch_oracle.csv
PUNCH_HEIGHT = 0.02


def oracle_force(depth):
    """The FEM oracle's punch force (N) at `depth` (m) below the top, from punch_oracle.csv."""
    path = os.path.join(os.path.dirname(os.path.abspath(__file__)), 'punch_oracle.csv')
    with open(path) as f:
        rows = list(csv.DictReader(line for line in f if not line.startswith('#')))
    depths = [TOP - float(r['z']) for r in rows]
    forces = [float(r['fz']) for r in rows]
    k = min(range(len(rows)), key=lambda i: abs(depths[i] - depth))
    if abs(depths[k] - depth) > 1e-9:
        raise ValueError('punch_oracle.csv has no sample at %g m' % depth)
    return forces[k]


class IndentTest(unittest.TestCase):

    @classmethod
    def setUpClass(cls):
        rospy.init_node('test_indent')
        cls.flsm = FlsmClient()
        cls.pub = cls.flsm.collider_publisher()

    def send(self, action, tool, bottom):
        """Adds, moves or removes `tool` ('sphere' or 'punch') with its lowest point at `bottom`."""
        m = ColliderCommand()
        m.action = action
        m.id = tool
        if tool == 'sphere':
            m.type = 'sphere'
            m.radius = RADIUS
            centre = bottom + RADIUS
        else:
            # (cells - 0.4) cells wide: PUNCH_CELLS x PUNCH_CELLS particles under it
            m.type = 'box'
            side = (PUNCH_CELLS - 0.4) * SPACING
            m.size.x, m.size.y, m.size.z = side, side, PUNCH_HEIGHT
            centre = bottom + 0.5 * PUNCH_HEIGHT
        m.pose.position = Point(0.0, 0.0, centre)
        m.pose.orientation = Quaternion(0, 0, 0, 1)
        m.static_friction = 0.0
        m.kinetic_friction = 0.0
        self.pub.publish(m)

    def press(self, tool):
        """Presses `tool` DEPTH into the resting block and returns its ~contact_wrenches entry
        (force, particles in contact) once the block rests again; then removes it."""
        f = self.flsm
        s = f.wait_state(lambda s: s.idle and s.colliders == 0, 60.0)
        self.assertIsNotNone(s, 'the block did not come to rest')
        self.assertEqual(s.particles, 21 * 21 * 12)
        self.assertFalse(s.stiffness_saturated)
        # The tool starts 0.5 mm above the top and is lowered by 0.25 mm a command (less than a
        # particle's radius: pressed in, not placed inside), 10 Hz, to DEPTH.
        self.send(ColliderCommand.ADD, tool, TOP + 0.0005)
        self.assertIsNotNone(f.wait_state(lambda s: s.colliders >= 1, 5.0), 'ADD not applied')
        travel = 0.0005 + DEPTH
        moves = int(round(travel / 0.00025))
        for k in range(1, moves + 1):
            self.send(ColliderCommand.MOVE, tool, TOP + 0.0005 - travel * k / moves)
            time.sleep(0.1)
        steps = f.state().steps
        f.wait_state(lambda s: s.steps > steps + 30, 10.0)
        self.assertIsNotNone(f.wait_state(lambda s: s.idle, 60.0), 'the pressed block did not rest')
        msg = rospy.wait_for_message('/flsm_node/contact_wrenches', ContactWrenches, 5.0)
        k = list(msg.ids).index(tool)
        self.send(ColliderCommand.REMOVE, tool, 0.0)
        self.assertIsNotNone(f.wait_state(lambda s: s.colliders == 0, 5.0), 'REMOVE not applied')
        return msg.wrenches[k].wrench.force, msg.contacts[k]

    def test_sphere_force_follows_hertz(self):
        force, contacts = self.press('sphere')
        thickness = TOP - 0.5 * SPACING   # from the pinned centres to the top face
        hertz = hertz_on_bonded_layer(RADIUS, DEPTH, thickness, E, NU)
        rospy.loginfo('indent: %.4f N on %d particles; Hertz on the bonded layer %.4f N (%+.1f %%)',
                      force.z, contacts, hertz, 100.0 * (force.z / hertz - 1.0))
        self.assertGreater(contacts, 9)
        self.assertAlmostEqual(force.z / hertz, 1.0, delta=0.15)
        self.assertLess(math.hypot(force.x, force.y), 0.02 * force.z)

    def test_punch_force_follows_the_fem_oracle(self):
        force, contacts = self.press('punch')
        oracle = oracle_force(DEPTH)
        rospy.loginfo('indent: punch %.4f N on %d particles; FEM oracle %.4f N (%+.1f %%)',
                      force.z, contacts, oracle, 100.0 * (force.z / oracle - 1.0))
        self.assertEqual(contacts, PUNCH_CELLS * PUNCH_CELLS)
        self.assertAlmostEqual(force.z / oracle, 1.0, delta=0.10)
        self.assertLess(math.hypot(force.x, force.y), 0.02 * force.z)


if __name__ == '__main__':
    rostest.rosrun(PKG, 'indent', IndentTest)
