#!/usr/bin/env python3
"""DragCommand ATTACH end to end: a frame 'gripper' broadcast on tf moves and turns; the
particles attached to it keep their offsets in it (read back from ~particles); when the frame
is no longer broadcast they are held still; an unknown frame is refused. The scene is
test/ros/coarse_bunny.yaml: the bunny on a pinned base, no gravity."""

import math
import threading
import time
import unittest

import numpy as np
import rospy
import rostest
import tf2_ros
from geometry_msgs.msg import TransformStamped
from sensor_msgs import point_cloud2
from sensor_msgs.msg import PointCloud2

from deformable_flsm.msg import DragCommand
from flsm_testing import FlsmClient, top_particle

PKG = 'deformable_flsm'
# How many particles the attach takes, and the frame's motion: it turns about its own z axis
# back and forth by TURN rad and sways by SWAY m along y, with period PERIOD s.
COUNT = 10
TURN = 0.6
SWAY = 0.02
PERIOD = 4.0
# tf and the node's steps and publishing come between the frame's pose and the cloud that shows
# it: the check allows the cloud to show the frame as it was up to MAX_LAG s before its stamp.
MAX_LAG = 0.3
LAG_STEP = 0.005
# How closely the attached particles must keep their offsets (m), at the best lag. They follow
# the frame exactly (a hard attach); what is left is the lag's resolution (the frame moves
# < 0.05 m/s: 0.25 mm per 5 ms) and the cloud's float32 rounding.
TOLERANCE = 1e-3


def rotation_z(angle):
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def quaternion_z(angle):
    return (0.0, 0.0, math.sin(0.5 * angle), math.cos(0.5 * angle))


class Gripper(object):
    """Broadcasts the frame 'gripper' in 'world' at 50 Hz: at `origin`, still until move() and
    then swaying and turning; stop() ends the broadcast."""

    def __init__(self, origin):
        self.origin = np.asarray(origin, dtype=float)
        self.start = None  # wall time the motion started (None: still)
        self.running = True
        self.broadcaster = tf2_ros.TransformBroadcaster()
        self.thread = threading.Thread(target=self.run)
        self.thread.daemon = True
        self.thread.start()

    def pose(self, t):
        """(R, p) of the frame at ROS time t (s)."""
        if self.start is None or t <= self.start:
            return np.eye(3), self.origin.copy()
        phase = 2.0 * math.pi * (t - self.start) / PERIOD
        return (rotation_z(TURN * math.sin(phase)),
                self.origin + np.array([0.0, SWAY * math.sin(phase), 0.0]))

    def angle(self, t):
        if self.start is None or t <= self.start:
            return 0.0
        return TURN * math.sin(2.0 * math.pi * (t - self.start) / PERIOD)

    def move(self):
        self.start = rospy.Time.now().to_sec()

    def stop(self):
        self.running = False
        self.thread.join()

    def run(self):
        rate = rospy.Rate(50.0)
        while self.running and not rospy.is_shutdown():
            now = rospy.Time.now()
            _, p = self.pose(now.to_sec())
            t = TransformStamped()
            t.header.stamp = now
            t.header.frame_id = 'world'
            t.child_frame_id = 'gripper'
            t.transform.translation.x, t.transform.translation.y, t.transform.translation.z = p
            q = quaternion_z(self.angle(now.to_sec()))
            (t.transform.rotation.x, t.transform.rotation.y, t.transform.rotation.z,
             t.transform.rotation.w) = q
            self.broadcaster.sendTransform(t)
            rate.sleep()


class AttachTest(unittest.TestCase):

    @classmethod
    def setUpClass(cls):
        rospy.init_node('test_attach')
        cls.flsm = FlsmClient()

    def setUp(self):
        self.assertIsNotNone(self.flsm.settle(), 'the node did not come to rest')

    def clouds(self, seconds):
        """(stamp, #P x 3 positions) of every ~particles message for `seconds` s."""
        got = []
        sub = rospy.Subscriber(self.flsm.node + '/particles', PointCloud2,
                               lambda m: got.append(m), queue_size=100)
        time.sleep(seconds)
        sub.unregister()
        return [(m.header.stamp.to_sec(),
                 np.array(list(point_cloud2.read_points(m, field_names=('x', 'y', 'z')))))
                for m in got]

    def test_attached_particles_keep_their_offsets_in_a_moving_turning_frame(self):
        f = self.flsm
        x = f.particles()
        ear = x[top_particle(x)]
        # The frame 2 cm above the ear tip, so that its turning carries the particles round;
        # the grab point just below its origin, off every lattice symmetry (no ties in distance).
        gripper = Gripper(ear + np.array([0.0, 0.0, 0.02]))
        try:
            point = np.array([1e-4, 2e-4, -0.02 + 3e-4])
            grabbed = np.argsort(np.linalg.norm(x - (gripper.origin + point), axis=1))[:COUNT]
            local = x[grabbed] - gripper.origin  # offsets in the frame (unturned at the grab)
            time.sleep(0.5)  # tf reaches the node
            f.drag(DragCommand.ATTACH, 'gripper', point=tuple(point), count=COUNT, frame='gripper')
            self.assertIsNotNone(f.wait_state(lambda s: s.active_drags == 1, 5.0),
                                 'the attach was not accepted: %s' % f.state().last_rejection)
            gripper.move()
            clouds = self.clouds(PERIOD)
            self.assertGreater(len(clouds), 30)
            worst, worst_lag, turned = 0.0, 0.0, 0.0
            for stamp, y in clouds:
                best = None
                for lag in np.arange(0.0, MAX_LAG, LAG_STEP):
                    R, p = gripper.pose(stamp - lag)
                    e = np.max(np.linalg.norm(y[grabbed] - (local.dot(R.T) + p), axis=1))
                    if best is None or e < best[0]:
                        best = (e, lag)
                worst = max(worst, best[0])
                worst_lag = max(worst_lag, best[1])
                turned = max(turned, abs(gripper.angle(stamp)))
            rospy.loginfo('attach: %d clouds over %.1f s, the frame turned up to %.2f rad; '
                          'worst offset error %.2f mm at lags up to %.0f ms',
                          len(clouds), PERIOD, turned, 1e3 * worst, 1e3 * worst_lag)
            self.assertGreater(turned, 0.5)  # the frame did turn
            self.assertLess(worst, TOLERANCE)

            # The frame is no longer broadcast: after 0.5 s its newest transform is stale and
            # the attached particles hold where it was last seen.
            gripper.stop()
            time.sleep(1.0)
            held = self.clouds(1.0)
            self.assertGreater(len(held), 5)
            drift = max(np.max(np.linalg.norm(y[grabbed] - held[0][1][grabbed], axis=1))
                        for _, y in held)
            rospy.loginfo('attach: frame lost, the attached particles moved %.3f mm in 1 s',
                          1e3 * drift)
            self.assertLess(drift, 1e-4)
            self.assertEqual(f.state().active_drags, 1)
        finally:
            gripper.stop() if gripper.running else None
            f.release('gripper')

    def test_attach_to_an_unknown_frame_is_refused(self):
        f = self.flsm
        before = f.rejected('unknown_frame')
        f.drag(DragCommand.ATTACH, 'nowhere', point=(0.0, 0.0, 0.0), count=3, frame='no_such_frame')
        self.assertIsNotNone(f.wait_state(lambda s: f.rejected('unknown_frame') > before, 10.0))
        self.assertEqual(f.state().active_drags, 0)


if __name__ == '__main__':
    rostest.rosrun(PKG, 'attach', AttachTest)
