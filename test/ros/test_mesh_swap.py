#!/usr/bin/env python3
"""Any mesh starts with the default parameters (config/flsm.yaml, tuned for the bunny): the
horse through the default launch, then every model of glmark2-data and a user's STL in
millimetres (mesh_scale 0.001), each with its own node started against the rostest's master.
Started means: ~state arrives, the solver steps, and every figure it reports is finite."""

import glob
import math
import os
import shutil
import struct
import subprocess
import tempfile
import time
import unittest

import roslib.packages
import rosparam
import rospy
import rostest

from deformable_flsm.msg import SimulationState

PKG = 'deformable_flsm'
MODELS = '/usr/share/glmark2/models'
# Voxelizing with a particle budget and timing a few steps take a few seconds per mesh; the
# machine may be busy.
START_TIMEOUT_S = 90.0


def node_binary():
    paths = roslib.packages.find_node(PKG, 'flsm_node')
    if not paths:
        raise RuntimeError('flsm_node not found: is the workspace built and sourced?')
    return paths[0]


def write_box_stl(path, size_mm):
    """A closed, axis-aligned box of `size_mm` millimetres per side, binary STL."""
    s = float(size_mm)
    corners = [(x, y, z) for x in (0.0, s) for y in (0.0, s) for z in (0.0, s)]
    # Two outward-facing triangles per face, as indices into `corners` (x major, then y, z).
    faces = [(0, 1, 3), (0, 3, 2), (4, 6, 7), (4, 7, 5),   # x = 0, x = s
             (0, 4, 5), (0, 5, 1), (2, 3, 7), (2, 7, 6),   # y = 0, y = s
             (0, 2, 6), (0, 6, 4), (1, 5, 7), (1, 7, 3)]   # z = 0, z = s
    with open(path, 'wb') as f:
        f.write(b'box written by test_mesh_swap'.ljust(80, b' '))
        f.write(struct.pack('<I', len(faces)))
        for a, b, c in faces:
            f.write(struct.pack('<3f', 0.0, 0.0, 0.0))  # readers recompute the normal
            for i in (a, b, c):
                f.write(struct.pack('<3f', *corners[i]))
            f.write(struct.pack('<H', 0))


def finite_state(msg):
    return all(math.isfinite(v) for v in (
        msg.sim_time, msg.kinetic_energy, msg.max_displacement, msg.max_speed, msg.shape_error,
        msg.alpha, msg.step_time))


class StateWatch(object):
    def __init__(self, node):
        self.last = None
        self.count = 0
        self.non_finite = 0
        self.sub = rospy.Subscriber(node + '/state', SimulationState, self.on_state, queue_size=10)

    def on_state(self, msg):
        self.last = msg
        self.count += 1
        if not finite_state(msg):
            self.non_finite += 1

    def wait_steps(self, steps, timeout, proc=None):
        end = time.time() + timeout
        while time.time() < end:
            if proc is not None and proc.poll() is not None:
                return False
            if self.last is not None and self.last.steps >= steps:
                return True
            time.sleep(0.1)
        return False


class MeshSwapTest(unittest.TestCase):

    def test_horse_through_the_default_launch(self):
        watch = StateWatch('/flsm_node')
        self.assertTrue(watch.wait_steps(30, START_TIMEOUT_S),
                        'flsm_node with horse.3ds did not step 30 times')
        self.assertGreater(watch.last.particles, 0)
        self.assertEqual(watch.non_finite, 0, 'non-finite figures on ~state')
        watch.sub.unregister()

    def start_node(self, name, mesh, scale=None):
        """Starts flsm_node as /name with config/flsm.yaml and `mesh`; returns (ok, output)."""
        config = os.path.join(roslib.packages.get_pkg_dir(PKG), 'config', 'flsm.yaml')
        for params, ns in rosparam.load_file(config, default_namespace='/' + name):
            rosparam.upload_params(ns, params)
        rospy.set_param('/' + name + '/mesh', mesh)
        if scale is not None:
            rospy.set_param('/' + name + '/mesh_scale', scale)
        log = tempfile.TemporaryFile()
        proc = subprocess.Popen([node_binary(), '__name:=' + name], stdout=log,
                                stderr=subprocess.STDOUT, env=dict(os.environ))
        watch = StateWatch('/' + name)
        try:
            stepped = watch.wait_steps(30, START_TIMEOUT_S, proc)
            alive = proc.poll() is None
        finally:
            watch.sub.unregister()
            if proc.poll() is None:
                proc.terminate()
                try:
                    proc.wait(timeout=20)
                except subprocess.TimeoutExpired:
                    proc.kill()
                    proc.wait()
        log.seek(0)
        output = log.read().decode('utf-8', 'replace')
        log.close()
        ok = stepped and alive and watch.non_finite == 0 and watch.last.particles > 0
        return ok, output

    def test_every_glmark2_model_and_a_millimetre_stl(self):
        models = sorted(glob.glob(os.path.join(MODELS, '*')))
        self.assertGreater(len(models), 1, 'no glmark2-data models in ' + MODELS)
        tmp = tempfile.mkdtemp(prefix='flsm_mesh_swap_')
        try:
            stl = os.path.join(tmp, 'box_100mm.stl')
            write_box_stl(stl, 100.0)
            cases = [(m, None) for m in models if not m.endswith('horse.3ds')]
            cases.append((stl, 0.001))
            failed = []
            for i, (mesh, scale) in enumerate(cases):
                ok, output = self.start_node('flsm_mesh_%d' % i, mesh, scale)
                if not ok:
                    failed.append('%s:\n%s' % (mesh, output[-3000:]))
            self.assertEqual(failed, [], 'meshes that did not start and simulate:\n' +
                             '\n'.join(failed))
        finally:
            shutil.rmtree(tmp, ignore_errors=True)


if __name__ == '__main__':
    rospy.init_node('test_mesh_swap')
    rostest.rosrun(PKG, 'mesh_swap', MeshSwapTest)
