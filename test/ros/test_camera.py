#!/usr/bin/env python3
"""Depth cameras (~cameras) against what they must show:
- a ball collider and the ground seen from above read the depth of their rays (worked out here)
  within 1 mm, in metres (32FC1) and in millimetres (16UC1);
- Debian's depth_image_proc point_cloud_xyz nodelet turns depth/image_raw and
  depth/camera_info into the cloud the node publishes as depth/points, in both encodings;
- the cube's mask covers the pixels image_geometry's pinhole model projects its top face to, and
  what the camera sees of it lies on the face ~surface gives;
- depth, rgb, mask and points of one frame carry one stamp."""

import math
import threading
import time
import unittest

import numpy as np
import rospy
import rostest
import tf2_ros
from geometry_msgs.msg import TransformStamped
from image_geometry import PinholeCameraModel
from sensor_msgs import point_cloud2
from sensor_msgs.msg import CameraInfo, Image, PointCloud2

from deformable_flsm.msg import SimulationState

PKG = 'deformable_flsm'
TIMEOUT_S = 60.0
PROBE = np.array([1.0, 0.0, 0.8])   # camera.test: the probe cameras, looking down
TOP = np.array([0.0, 0.0, 0.5])     # the top camera, looking down
BALL = np.array([1.0, 0.0, 0.1])    # camera.yaml
BALL_R = 0.05
LABEL_CUBE = 1


def image_array(msg):
    dtype = {'32FC1': np.float32, '16UC1': np.uint16, 'rgb8': np.uint8}[msg.encoding]
    channels = 3 if msg.encoding == 'rgb8' else 1
    a = np.frombuffer(msg.data, dtype=dtype).reshape(msg.height, msg.width, channels)
    return a[:, :, 0] if channels == 1 else a


def cloud_array(msg):
    pts = np.array(list(point_cloud2.read_points(msg, field_names=('x', 'y', 'z'), skip_nans=False)),
                   dtype=np.float64)
    return pts.reshape(msg.height, msg.width, 3)


class Latest(object):
    """The newest messages of some topics, by stamp."""

    def __init__(self, topics):
        self.lock = threading.Lock()
        self.msgs = {t: {} for t, _ in topics}
        self.subs = [rospy.Subscriber(t, c, self.keep(t), queue_size=5) for t, c in topics]

    def keep(self, topic):
        def on(msg):
            with self.lock:
                self.msgs[topic][msg.header.stamp] = msg
        return on

    def wait_common(self, timeout=TIMEOUT_S):
        """A stamp every topic has a message of, and those messages."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            with self.lock:
                common = set.intersection(*[set(m) for m in self.msgs.values()])
                if common:
                    stamp = max(common)
                    return stamp, {t: m[stamp] for t, m in self.msgs.items()}
            time.sleep(0.05)
        raise AssertionError('no stamp common to %s' % list(self.msgs))

    def close(self):
        for s in self.subs:
            s.unregister()


def analytic_depth(info, ground_z):
    """Per pixel, the depth of the ball or the ground seen by the probe camera."""
    K = np.array(info.K).reshape(3, 3)
    u, v = np.meshgrid(np.arange(info.width), np.arange(info.height))
    x = (u - K[0, 2]) / K[0, 0]
    y = (v - K[1, 2]) / K[1, 1]
    # optical (x, y, 1) looking down: world (x, -y, -1)
    d = np.stack([x, -y, -np.ones_like(x)], axis=-1)
    t_plane = (PROBE[2] - ground_z) * np.ones_like(x)
    oc = PROBE - BALL
    a = (d * d).sum(-1)
    b = 2.0 * (d @ oc)
    c = oc @ oc - BALL_R ** 2
    disc = b * b - 4 * a * c
    hit = disc > 0
    t_ball = np.where(hit, (-b - np.sqrt(np.maximum(disc, 0))) / (2 * a), np.inf)
    depth = np.minimum(t_plane, t_ball)
    silhouette = np.abs(disc) < 2e-4  # rays that graze the ball
    return depth, silhouette


class CameraTest(unittest.TestCase):

    @classmethod
    def setUpClass(cls):
        # the cameras' optical frames, looking straight down: half a turn about x
        cls.static = tf2_ros.StaticTransformBroadcaster()
        frames = []
        for name, at in (('top_optical', TOP), ('probe_optical', PROBE)):
            t = TransformStamped()
            t.header.stamp = rospy.Time.now()
            t.header.frame_id = 'world'
            t.child_frame_id = name
            t.transform.translation.x, t.transform.translation.y, t.transform.translation.z = at
            t.transform.rotation.x = 1.0
            frames.append(t)
        cls.static.sendTransform(frames)
        rospy.wait_for_message('/flsm_node/state', SimulationState, timeout=TIMEOUT_S)
        cls.tf = tf2_ros.Buffer()
        cls.listener = tf2_ros.TransformListener(cls.tf)
        t = cls.tf.lookup_transform('world', 'flsm_collider/ground', rospy.Time(0), rospy.Duration(10.0))
        cls.ground_z = t.transform.translation.z

    def test_ball_and_ground_have_the_depth_of_their_rays_in_both_encodings(self):
        latest = Latest([('/flsm_node/probe/depth/image_raw', Image),
                         ('/flsm_node/probe/depth/camera_info', CameraInfo)])
        _, m = latest.wait_common()
        latest.close()
        info = m['/flsm_node/probe/depth/camera_info']
        depth = image_array(m['/flsm_node/probe/depth/image_raw']).astype(np.float64)
        expected, silhouette = analytic_depth(info, self.ground_z)
        err = np.abs(depth - expected)[~silhouette]
        self.assertLess(float(err.max()), 1e-3, 'depth off by up to %.4f m' % err.max())
        self.assertGreater(int((expected < PROBE[2] - self.ground_z - 1e-3).sum()), 200,
                           'the ball fills too few pixels to tell')
        mm = rospy.wait_for_message('/flsm_node/probe_mm/depth/image_raw', Image, timeout=TIMEOUT_S)
        self.assertEqual(mm.encoding, '16UC1')
        err_mm = np.abs(image_array(mm).astype(np.float64) / 1000.0 - expected)[~silhouette]
        self.assertLess(float(err_mm.max()), 1e-3, 'millimetre depth off by up to %.4f m' % err_mm.max())

    def test_depth_image_proc_makes_the_cloud_the_node_publishes(self):
        ours = Latest([('/flsm_node/probe/depth/points', PointCloud2), ('/xyz_m/points', PointCloud2)])
        _, m = ours.wait_common()
        ours.close()
        a = cloud_array(m['/flsm_node/probe/depth/points'])
        b = cloud_array(m['/xyz_m/points'])
        seen = np.isfinite(a).all(-1) & np.isfinite(b).all(-1)
        self.assertGreater(int(seen.sum()), 0.9 * seen.size)
        err = np.linalg.norm(a - b, axis=-1)[seen]
        self.assertLess(float(err.max()), 2e-3, 'depth_image_proc (32FC1) differs by %.4f m' % err.max())
        # millimetres: the same cloud within their rounding
        mm = rospy.wait_for_message('/xyz_mm/points', PointCloud2, timeout=TIMEOUT_S)
        c = cloud_array(mm)
        seen = np.isfinite(a).all(-1) & np.isfinite(c).all(-1)
        err = np.linalg.norm(a - c, axis=-1)[seen]
        self.assertLess(float(err.max()), 2e-3, 'depth_image_proc (16UC1) differs by %.4f m' % err.max())

    def test_cube_mask_covers_the_projected_top_face_and_lies_on_the_surface(self):
        latest = Latest([('/flsm_node/top/mask', Image), ('/flsm_node/top/depth/points', PointCloud2),
                         ('/flsm_node/top/rgb/image_raw', Image), ('/flsm_node/top/depth/image_raw', Image),
                         ('/flsm_node/top/depth/camera_info', CameraInfo)])
        _, m = latest.wait_common()  # one stamp for all five
        latest.close()
        surface = rospy.wait_for_message('/flsm_node/surface', PointCloud2, timeout=TIMEOUT_S)
        verts = np.array(list(point_cloud2.read_points(surface, field_names=('x', 'y', 'z'))))
        lo, hi = verts.min(axis=0), verts.max(axis=0)
        model = PinholeCameraModel()
        model.fromCameraInfo(m['/flsm_node/top/depth/camera_info'])
        # the top face's corners in the optical frame (x, -y, 0.5 - z)
        us, vs = [], []
        for x in (lo[0], hi[0]):
            for y in (lo[1], hi[1]):
                u, v = model.project3dToPixel((x, -y, TOP[2] - hi[2]))
                us.append(u)
                vs.append(v)
        mask = image_array(m['/flsm_node/top/mask'])
        rows, cols = np.nonzero(mask == LABEL_CUBE)
        self.assertGreater(len(rows), 100)
        # a pixel is the cube's when its centre's ray meets the face: the first and last pixel
        # centres within the projected edges
        self.assertLessEqual(abs(cols.min() - math.ceil(min(us))), 1, (cols.min(), us))
        self.assertLessEqual(abs(cols.max() - math.floor(max(us))), 1, (cols.max(), us))
        self.assertLessEqual(abs(rows.min() - math.ceil(min(vs))), 1, (rows.min(), vs))
        self.assertLessEqual(abs(rows.max() - math.floor(max(vs))), 1, (rows.max(), vs))
        self.assertTrue(set(np.unique(mask)) <= {LABEL_CUBE, 1000, 1001}, np.unique(mask))
        # what the camera sees of the cube lies on the face ~surface gives
        pts = cloud_array(m['/flsm_node/top/depth/points'])[mask == LABEL_CUBE]
        world_z = TOP[2] - pts[:, 2]
        self.assertLess(float(np.abs(world_z - hi[2]).max()), 2e-3)
        rgb = image_array(m['/flsm_node/top/rgb/image_raw'])
        self.assertTrue((rgb[mask == LABEL_CUBE].sum(-1) > 0).all(), 'the cube is drawn black')


if __name__ == '__main__':
    rospy.init_node('test_camera')
    rostest.rosrun(PKG, 'camera', CameraTest)
