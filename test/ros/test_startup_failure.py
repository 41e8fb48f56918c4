#!/usr/bin/env python3
"""flsm_node must refuse to start on a bad ~mesh or parameter: exit code != 0 and a fatal
message that names what to fix. Runs the node binary against the rostest's master."""

import os
import subprocess
import unittest

import roslib.packages
import rospy
import rostest

PKG = 'deformable_flsm'
# Generous: the node only has to reach the master, read parameters and fail.
TIMEOUT_S = 60.0


def find_node_binary():
    paths = roslib.packages.find_node(PKG, 'flsm_node')
    if not paths:
        raise RuntimeError('flsm_node not found: is the workspace built and sourced?')
    return paths[0]


class StartupFailureTest(unittest.TestCase):

    def run_node(self, name, *params):
        """Runs flsm_node as /<name> with private params `_key:=value`; returns (code, output).
        Each case uses its own node name, so that parameters left on the master by one case
        cannot leak into another."""
        cmd = [find_node_binary(), '__name:=' + name] + list(params)
        proc = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                              timeout=TIMEOUT_S, env=dict(os.environ), check=False)
        return proc.returncode, proc.stdout.decode('utf-8', 'replace')

    def assert_fails_naming(self, name, expected, *params):
        code, out = self.run_node(name, *params)
        self.assertNotEqual(code, 0, 'flsm_node exited 0 with %s; output:\n%s' % (params, out))
        self.assertIn('FATAL', out, 'no fatal message; output:\n%s' % out)
        for text in expected:
            self.assertIn(text, out, 'message does not mention %r; output:\n%s' % (text, out))

    def test_missing_mesh_file_is_named(self):
        missing = '/nonexistent/flsm_test/no_such_mesh.obj'
        self.assert_fails_naming('flsm_missing_mesh', [missing, '~mesh'], '_mesh:=' + missing)

    def test_unknown_package_url_is_named(self):
        self.assert_fails_naming('flsm_bad_package', ['no_such_package_flsm', '~mesh'],
                                 '_mesh:=package://no_such_package_flsm/bunny.obj')

    def test_negative_publish_rate_is_refused(self):
        self.assert_fails_naming('flsm_negative_rate', ['~publish_rate is -1', '(0, 1000]'],
                                 '_publish_rate:=-1')

    def test_clock_on_wall_time_that_needs_simulated_time_is_refused(self):
        # /use_sim_time is not set in this test: ~clock sim would serve a clock nobody reads
        self.assert_fails_naming('flsm_sim_clock', ["~clock is 'sim'", '/use_sim_time', 'sim_time:=true'],
                                 '_clock:=sim')

    def test_unknown_clock_is_refused(self):
        self.assert_fails_naming('flsm_bad_clock', ["~clock is 'gazebo'", "'follow'"], '_clock:=gazebo')

    def test_as_fast_as_it_can_on_wall_time_is_refused(self):
        self.assert_fails_naming('flsm_rtf0', ['~real_time_factor is 0', '~clock sim'],
                                 '_real_time_factor:=0.0')

    def test_camera_entry_that_is_wrong_names_the_entry_and_the_key(self):
        rospy.set_param('/flsm_bad_camera/cameras', [{'name': 'top', 'frame': 'cam', 'encoding': '8UC1'}])
        self.assert_fails_naming('flsm_bad_camera', ["~cameras entry 0 ('top')", 'encoding', '16UC1'])
        rospy.set_param('/flsm_bad_camera2/cameras', [{'name': 'top', 'frame': 'cam', 'widht': 320}])
        self.assert_fails_naming('flsm_bad_camera2', ["~cameras entry 0 ('top')", "unknown field 'widht'"])
        rospy.set_param('/flsm_bad_camera3/cameras', [{'name': 'top', 'frame': 'cam', 'near': 2.0, 'far': 1.0}])
        self.assert_fails_naming('flsm_bad_camera3', ["~cameras entry 0 ('top')", 'near 2', 'far 1'])

    def test_tactile_entry_that_is_wrong_names_the_entry_and_the_key(self):
        ball = {'id': 'ball', 'type': 'sphere', 'radius': 0.05, 'position': [1.0, 0.0, 0.0]}
        pad = {'id': 'pad', 'type': 'box', 'size': [0.1, 0.02, 0.1], 'position': [-1.0, 0.0, 0.0]}
        for name, entry, expected in (
                ('flsm_tactile_unknown', {'name': 'left', 'collider': 'nothing', 'face': '+y'},
                 ["~tactile entry 0 ('left')", "collider 'nothing' is not one of ~colliders"]),
                ('flsm_tactile_sphere', {'name': 'left', 'collider': 'ball', 'face': '+y'},
                 ["~tactile entry 0 ('left')", "'ball' is a sphere", 'box']),
                ('flsm_tactile_face', {'name': 'left', 'collider': 'pad', 'face': 'y'},
                 ["~tactile entry 0 ('left')", "face is 'y'", "'+x'"]),
                ('flsm_tactile_rows', {'name': 'left', 'collider': 'pad', 'face': '+y', 'rows': 0},
                 ["~tactile entry 0 ('left')", 'rows is 0'])):
            rospy.set_param('/%s/colliders' % name, [ball, pad])
            rospy.set_param('/%s/tactile' % name, [entry])
            self.assert_fails_naming(name, expected)

    def test_nan_publish_rate_is_refused(self):
        # roscpp reads `_x:=.nan` as a string, so a NaN can only arrive through the parameter
        # server (a YAML file loaded by a launch file): put it there.
        rospy.set_param('/flsm_nan_rate/publish_rate', float('nan'))
        self.assert_fails_naming('flsm_nan_rate', ['~publish_rate is nan', 'finite'])

    def test_non_numeric_publish_rate_is_refused(self):
        self.assert_fails_naming('flsm_text_rate', ['~publish_rate', 'a number', "'fast'"],
                                 '_publish_rate:=fast')

    def test_zero_mesh_scale_is_refused(self):
        self.assert_fails_naming('flsm_zero_scale', ['~mesh_scale is 0', '> 0'], '_mesh_scale:=0')

    def test_unknown_solver_is_refused(self):
        self.assert_fails_naming('flsm_bad_solver', ["~solver is 'fastest'", "'fast'", "'naive'"],
                                 '_solver:=fastest')

    def test_unknown_implicit_scheme_is_refused(self):
        self.assert_fails_naming('flsm_bad_scheme', ["~implicit_scheme is 'bdf3'", "'backward_euler'", "'bdf2'"],
                                 '_implicit_scheme:=bdf3')

    def test_spacing_and_resolution_together_are_refused(self):
        self.assert_fails_naming('flsm_both_lattice', ['~spacing', '~resolution', 'both set'],
                                 '_spacing:=0.01', '_resolution:=12')

    def test_region_radius_and_half_width_together_are_refused(self):
        self.assert_fails_naming('flsm_both_region', ['~region_radius', '~region_half_width'],
                                 '_region_radius:=0.03', '_region_half_width:=2')

    def test_fractional_resolution_is_refused(self):
        self.assert_fails_naming('flsm_float_resolution', ['~resolution', 'an integer'],
                                 '_resolution:=12.5')

    def test_number_for_a_flag_is_refused(self):
        self.assert_fails_naming('flsm_int_flag', ['~republish_at_rest', 'true or false'],
                                 '_republish_at_rest:=1')

    def test_stiffness_above_one_is_refused(self):
        self.assert_fails_naming('flsm_stiff', ['stiffness', '(0, 1]'], '_stiffness:=1.5')

    def test_non_positive_youngs_modulus_is_refused(self):
        # 0 once meant "classic FastLSM": now that has its own switch, ~material.
        self.assert_fails_naming('flsm_negative_modulus', ['~youngs_modulus is -5', '> 0',
                                                           '~material'],
                                 '_youngs_modulus:=-5.0')
        self.assert_fails_naming('flsm_zero_modulus', ['~youngs_modulus is 0', '~material'],
                                 '_youngs_modulus:=0.0')

    def test_unknown_material_is_refused(self):
        self.assert_fails_naming('flsm_bad_material', ["~material is 'rubber'", "'youngs'",
                                                      "'classic'"], '_material:=rubber')

    def test_zero_substeps_is_refused(self):
        self.assert_fails_naming('flsm_substeps', ['substeps', '1 to'], '_substeps:=0')

    def test_malformed_gravity_is_refused(self):
        rospy.set_param('/flsm_bad_gravity/gravity', [0.0, -9.81])
        self.assert_fails_naming('flsm_bad_gravity', ['~gravity', 'three numbers'])

    def test_malformed_pinned_box_is_refused(self):
        rospy.set_param('/flsm_bad_pin/pinned', [[0.0, 0.0, 0.0, 1.0, 1.0]])
        self.assert_fails_naming('flsm_bad_pin', ['~pinned', 'entry 0', 'six numbers'])

    def test_inverted_pinned_box_is_refused(self):
        rospy.set_param('/flsm_inverted_pin/pinned', [[0.1, 0.0, 0.0, 0.0, 1.0, 1.0]])
        self.assert_fails_naming('flsm_inverted_pin', ['~pinned box 0', 'min <= max'])

    def test_duplicate_object_name_is_refused(self):
        rospy.set_param('/flsm_twin_objects/objects',
                        [{'name': 'cube', 'resolution': 4}, {'name': 'cube', 'resolution': 4}])
        self.assert_fails_naming('flsm_twin_objects', ['~objects entry 1', "'cube'",
                                                       'used by an earlier entry'])

    def test_unknown_object_key_is_refused(self):
        rospy.set_param('/flsm_object_typo/objects', [{'name': 'cube', 'youngs_modulos': 1e4}])
        self.assert_fails_naming('flsm_object_typo', ['~objects entry 0', "'cube'",
                                                      "unknown key 'youngs_modulos'"])

    def test_bad_object_value_is_refused(self):
        rospy.set_param('/flsm_object_negative/objects', [{'name': 'cube', 'youngs_modulus': -5.0}])
        self.assert_fails_naming('flsm_object_negative', ['~objects entry 0', "'cube'",
                                                          'youngs_modulus is -5'])

    def test_objects_inside_each_other_are_refused_naming_both(self):
        rospy.set_param('/flsm_overlap/objects',
                        [{'name': 'first', 'resolution': 4, 'pose': [0.0, 0.0, 0.0]},
                         {'name': 'second', 'resolution': 4, 'pose': [0.02, 0.0, 0.0]}])
        self.assert_fails_naming('flsm_overlap', ["'first'", "'second'", 'pose'])

    def test_lattice_over_max_particles_is_refused(self):
        self.assert_fails_naming('flsm_too_fine', ['~max_particles', 'resolution'],
                                 '_resolution:=60', '_max_particles:=1000')


if __name__ == '__main__':
    rostest.rosrun(PKG, 'startup_failure', StartupFailureTest)
