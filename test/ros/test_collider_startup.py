#!/usr/bin/env python3
"""flsm_node refuses to start on a bad ~colliders entry or ~ground_clearance, naming the entry
and the field to fix."""

import unittest

import rospy
import rostest

from test_startup_failure import StartupFailureTest

PKG = 'deformable_flsm'


def box(**fields):
    entry = {'id': 'b', 'type': 'box', 'size': [0.1, 0.1, 0.1]}
    entry.update(fields)
    return entry


class ColliderStartupTest(unittest.TestCase):
    run_node = StartupFailureTest.run_node
    assert_fails_naming = StartupFailureTest.assert_fails_naming

    def fails(self, name, colliders, expected):
        rospy.set_param('/%s/colliders' % name, colliders)
        self.assert_fails_naming(name, ['~colliders'] + expected)

    def test_unknown_type(self):
        self.fails('flsm_c_type', [box(type='cone')], ['entry 0', "'b'", "'cone'", 'plane, box'])

    def test_negative_size(self):
        self.fails('flsm_c_size', [box(), box(id='c', size=[0.1, -0.1, 0.1])],
                   ['entry 1', "'c'", 'size', '> 0'])

    def test_nan_radius(self):
        self.fails('flsm_c_nan', [{'id': 's', 'type': 'sphere', 'radius': float('nan')}],
                   ["'s'", 'radius', 'finite'])

    def test_zero_quaternion(self):
        self.fails('flsm_c_quat', [box(orientation=[0, 0, 0, 0])], ['orientation', 'zero'])

    def test_missing_mesh_file(self):
        missing = '/nonexistent/flsm_test/no_such_collider.obj'
        self.fails('flsm_c_mesh', [{'id': 'm', 'type': 'mesh', 'mesh': missing}],
                   ["'m'", missing])

    def test_duplicate_id(self):
        self.fails('flsm_c_dup', [box(), box()], ['entry 1', "'b'", 'earlier entry'])

    def test_ground_id_taken(self):
        self.fails('flsm_c_ground', [box(id='ground')], ["'ground'", '~ground'])

    def test_missing_size(self):
        self.fails('flsm_c_nosize', [{'id': 'b', 'type': 'box'}], ["'b'", 'needs size'])

    def test_misspelt_field(self):
        self.fails('flsm_c_field', [box(raduis=0.1)], ["'raduis'", 'misspelt'])

    def test_negative_ground_clearance(self):
        rospy.set_param('/flsm_c_clearance/ground_clearance', -0.1)
        self.assert_fails_naming('flsm_c_clearance', ['~ground_clearance is -0.1', '>= 0'])


if __name__ == '__main__':
    rospy.init_node('test_collider_startup', anonymous=True)
    rostest.rosrun(PKG, 'collider_startup', ColliderStartupTest)
