#!/usr/bin/env python3
"""The fit's round trip for a tap through ROS, in lockstep (fit_tap.test): a client moves the
node's plate with ~collider MOVE, its pose and its velocity over the next step, and takes each
step with ~step; the plate is pressed 2 mm into the block in 0.1 s and lifted clear at once, the
block left ringing. `rosbag record` of /tf, ~contact_wrenches and ~particles, then
deformable_flsm.fit on the bag (examples/fit/tap_fit.yaml, the particles as markers) gives back
the node's modulus, Poisson's ratio and region damping within 3 %. The replay moves the plate
linearly between its recorded poses at the steps' ends, as the node moved it: the round trip is
exact up to the fit's own tolerance."""

import os
import shutil
import subprocess
import tempfile
import time
import unittest

import rospy
import rostest
from geometry_msgs.msg import Pose, Twist

from deformable_flsm import fit as F
from deformable_flsm.msg import ColliderCommand
from deformable_flsm.recording import Recording
from deformable_flsm.srv import Step
from flsm_testing import stop_recording, wait_recording

PKG = 'deformable_flsm'
NODE = '/flsm_node'
TRUTH = {'youngs_modulus': 2000.0, 'poissons_ratio': 0.35, 'damping': 10.0}  # fit_tap.test
TOP, DEPTH, PRESS, LIFT = 0.05, 0.002, 0.1, 0.01  # as test_fit.py's simulated tap (m, s)
PLATE_OFFSET = 0.01      # the plate's centre over its bottom face (the tool frame's place)
STEP = 1.0 / 30.0        # squeeze_scene.yaml's time_step
SECONDS = 3.0


def tool_height(t):
    """The plate's bottom face: on the top for 0.1 s, DEPTH into it over PRESS, then LIFT clear."""
    if t < 0.1:
        return TOP
    if t < 0.1 + PRESS:
        return TOP - DEPTH * (t - 0.1) / PRESS
    return TOP + LIFT


class FitTapTest(unittest.TestCase):

    def drive(self, pub, step):
        """Each step: MOVE the plate to where it is at the step's start with the velocity that
        brings it to where it is at the step's end, then ~step. Returns the commanded poses at
        the steps' ends."""
        ends = []
        for k in range(int(round(SECONDS / STEP))):
            z0, z1 = tool_height(k * STEP), tool_height((k + 1) * STEP)
            m = ColliderCommand()
            m.action, m.id = ColliderCommand.MOVE, 'plate'
            m.pose = Pose()
            m.pose.position.z = z0 + PLATE_OFFSET
            m.pose.orientation.w = 1.0
            m.velocity = Twist()
            m.velocity.linear.z = (z1 - z0) / STEP
            pub.publish(m)
            # the command reaches the node's queue before the step is asked for (a topic and a
            # service are two connections; a busy machine delays one by tens of milliseconds, and
            # the path check below would name a command that missed its step)
            time.sleep(0.2)
            answer = step(1)
            self.assertTrue(answer.success, answer.message)
            ends.append((answer.time, z1))
        return ends

    def test_the_nodes_damping_comes_back_from_a_tap(self):
        rospy.init_node('test_fit_tap')
        rospy.wait_for_service(NODE + '/step', timeout=60.0)
        step = rospy.ServiceProxy(NODE + '/step', Step)
        pub = rospy.Publisher(NODE + '/collider', ColliderCommand, queue_size=10)
        deadline = time.time() + 30.0
        while pub.get_num_connections() == 0 and time.time() < deadline:
            time.sleep(0.05)
        out = tempfile.mkdtemp()
        bag = os.path.join(out, 'tap.bag')
        topics = ['/tf', NODE + '/contact_wrenches', NODE + '/particles']
        record = subprocess.Popen(['rosbag', 'record', '-O', bag] + topics,
                                  stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            problem = wait_recording(record, topics)
            self.assertEqual(problem, '', problem)
            ends = self.drive(pub, step)
            time.sleep(1.0)
        finally:
            closed = stop_recording(record, bag)
        self.assertTrue(closed, 'rosbag record did not close its bag within 60 s of being stopped')
        try:
            recording = Recording.from_bag(bag, 'flsm_collider/plate', NODE + '/contact_wrenches', 'world',
                                           collider='plate')
            recording.poses[:, 2] -= PLATE_OFFSET
            # the node moved the plate as commanded: each state's plate where that step ended (a
            # command that missed its step would show here, not as a fit that is off)
            commanded = dict((int(round(t / STEP)), z) for t, z in ends)
            stamps = recording.start + recording.times
            self.assertGreater(len(stamps), 0.9 * len(ends), 'states in the bag')
            off = [abs(z - commanded[int(round(t / STEP))]) for t, z in zip(stamps, recording.poses[:, 2])
                   if int(round(t / STEP)) in commanded]
            self.assertGreater(len(off), 0.9 * len(ends), 'states in the bag at the steps taken')
            self.assertLess(max(off), 1e-9, 'the plate left the commanded path')
            self.assertGreater(recording.forces[:, 2].max(), 0.1, 'the bag\'s largest plate force (N)')
            spec = F.FitSpec.from_yaml(os.path.join(os.path.dirname(F.package_config()), '..', 'examples', 'fit',
                                                    'tap_fit.yaml'), recording=bag,
                                       markers_topic=NODE + '/particles')
            cluster = F.Cluster(workers=2)
            try:
                result = F.fit(spec, os.path.join(out, 'fit'), cluster, recording, log=rospy.loginfo)
            finally:
                cluster.close()
            fitted = ', '.join('%s %.6g (%.5f of the node\'s)' % (n, result['parameters'][n],
                                                                    result['parameters'][n] / v)
                               for n, v in TRUTH.items())
            rospy.loginfo('fit_tap: %d samples, %s, error %.4f (force %.4f, markers %.4f)', len(recording.times),
                          fitted, result['cost'], result['force_cost'], result['marker_cost'])
            for name, value in TRUTH.items():
                self.assertAlmostEqual(result['parameters'][name] / value, 1.0, delta=0.03, msg=fitted)
        finally:
            shutil.rmtree(out, ignore_errors=True)


if __name__ == '__main__':
    rostest.rosrun(PKG, 'fit_tap', FitTapTest)
