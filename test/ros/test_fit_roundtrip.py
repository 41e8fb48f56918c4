#!/usr/bin/env python3
"""The fit's round trip through ROS (fit_roundtrip.test): the node's plate pressed 2 mm into the
block along the tf frame `tool` and lifted again, seen by the node's depth camera `side`;
`rosbag record` of /tf, /tf_static, ~contact_wrenches, ~particles and the camera's depth/points,
then deformable_flsm.fit on the bag gives back the node's modulus and Poisson's ratio within 3 %,
once with the particles as markers and once with the camera's cloud instead (cloud_topic: any
points, compared point to plane, turned from the camera's optical frame by the bag's /tf_static,
cropped to the block's side)."""

import os
import shutil
import subprocess
import tempfile
import unittest

import numpy as np
import rospy
import rostest
import tf2_ros
from geometry_msgs.msg import TransformStamped

from deformable_flsm import fit as F
from deformable_flsm.recording import Recording
from flsm_testing import FlsmClient, stop_recording, wait_recording

PKG = 'deformable_flsm'
MODULUS, NU = 35000.0, 0.35   # fit_roundtrip.test
TOP, DEPTH = 0.05, 0.002   # the block's top face; how far the plate goes in
PLATE_OFFSET = 0.01        # the plate collider's frame over the tool frame (squeeze_scene.yaml)
CLOUD = '/flsm_node/side/depth/points'
TOPICS = ['/tf', '/tf_static', '/flsm_node/contact_wrenches', '/flsm_node/particles', CLOUD]
# the block's +x side as the camera sees it (m, the simulation frame): not its pinned base, not
# the plate's edge (x 0.04) nor its bottom face
CLOUD_BOX = [0.015, -0.035, 0.006, 0.035, 0.035, 0.045]


def tool_height(t):
    """1 s on the surface, 3 s down, 2 s held, 3 s up, 1 s on the surface (m)."""
    d = DEPTH * np.clip(min((t - 1.0) / 3.0, 1.0 - (t - 6.0) / 3.0), 0.0, 1.0)
    return TOP - d


class FitRoundTripTest(unittest.TestCase):

    def test_the_nodes_modulus_comes_back_from_a_bag(self):
        rospy.init_node('test_fit_roundtrip')
        flsm = FlsmClient()
        self.assertIsNotNone(flsm.wait_state(lambda s: s.idle, 60.0), 'the block did not come to rest')
        out = tempfile.mkdtemp()
        bag = os.path.join(out, 'poke.bag')
        record = subprocess.Popen(['rosbag', 'record', '-O', bag] + TOPICS,
                                  stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            problem = wait_recording(record, TOPICS)
            self.assertEqual(problem, '', problem)
            tf = tf2_ros.TransformBroadcaster()
            rate = rospy.Rate(60.0)
            t0 = rospy.Time.now()
            while not rospy.is_shutdown():
                t = (rospy.Time.now() - t0).to_sec()
                if t > 10.0:
                    break
                m = TransformStamped()
                m.header.stamp = rospy.Time.now()
                m.header.frame_id, m.child_frame_id = 'world', 'tool'
                m.transform.translation.z = tool_height(t)
                m.transform.rotation.w = 1.0
                tf.sendTransform(m)
                rate.sleep()
            rospy.sleep(0.5)
        finally:
            closed = stop_recording(record, bag)
        self.assertTrue(closed, 'rosbag record did not close its bag within 60 s of being stopped')
        try:
            # the plate as the node moved it (its frame flsm_collider/plate, at each state's stamp):
            # the node steps a followed collider from the tool frame's newest sample along its
            # velocity, which can lead or lag the frame's stamps by part of a step; the plate's
            # frame is PLATE_OFFSET above the tool frame's (squeeze_scene.yaml)
            recording = Recording.from_bag(bag, 'flsm_collider/plate', '/flsm_node/contact_wrenches', 'world',
                                           collider='plate')
            recording.poses[:, 2] -= PLATE_OFFSET
            depth = TOP - recording.poses[:, 2]
            self.assertGreater(depth.max(), 0.99 * DEPTH, 'the bag\'s deepest tool pose (%d samples)'
                               % len(recording.times))
            self.assertGreater(recording.forces[:, 2].max(), 1.0, 'the bag\'s largest plate force (N)')
            example = os.path.join(os.path.dirname(F.package_config()), '..', 'examples', 'fit', 'squeeze_fit.yaml')
            cluster = F.Cluster(workers=2)
            try:
                for name, seen in (('markers', {'markers_topic': '/flsm_node/particles'}),
                                   ('cloud', {'cloud_topic': CLOUD, 'cloud_box': CLOUD_BOX})):
                    spec = F.FitSpec.from_yaml(example, recording=bag, **seen)
                    result = F.fit(spec, os.path.join(out, 'fit_' + name), cluster, recording, log=rospy.loginfo)
                    e, nu = result['parameters']['youngs_modulus'], result['parameters']['poissons_ratio']
                    fitted = ('with the %s: E %.0f Pa (%.4f of the node\'s), nu %.4f (%.4f) from %d samples, '
                              'error %.4f (force %.4f, %s %.4f)' % (name, e, e / MODULUS, nu, nu / NU,
                                                                   len(recording.times), result['cost'],
                                                                   result['force_cost'], name, result['marker_cost']))
                    rospy.loginfo('fit_roundtrip: ' + fitted)
                    self.assertAlmostEqual(e / MODULUS, 1.0, delta=0.03, msg=fitted)
                    self.assertAlmostEqual(nu / NU, 1.0, delta=0.03, msg=fitted)
            finally:
                cluster.close()
        finally:
            shutil.rmtree(out, ignore_errors=True)


if __name__ == '__main__':
    rostest.rosrun(PKG, 'fit_roundtrip', FitRoundTripTest)
