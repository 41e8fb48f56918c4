#!/usr/bin/env python3
"""Publishes /joint_states along waypoints, in a process of its own.

The robot rostests drive robot_state_publisher through this player rather than through a thread
of the test: the test's own callbacks (a Python tf listener, ~contact_wrenches, ~state) share
its interpreter and can hold a publishing thread up for longer than the node's 0.5 s stale time
on a loaded machine, which would stop the robot's links in the simulation for reasons of the
test's own making.

Protocol: one JSON object per line on stdin, each replacing the schedule:
  {"names": [...], "waypoints": [[t, [q...]], ...], "pauses": [[t0, t1], ...]}
with t in ROS seconds; each position is held after its time and approached smoothly (a cosine
ease) before it; nothing is published within a pause. Published at RATE Hz until stdin closes.
"""

import json
import math
import sys
import threading

import rospy
from sensor_msgs.msg import JointState

RATE = 100.0


def smooth(s):
    """0 -> 1 with zero velocity at both ends."""
    s = min(1.0, max(0.0, s))
    return 0.5 - 0.5 * math.cos(math.pi * s)


class Player(object):

    def __init__(self):
        self.lock = threading.Lock()
        self.schedule = None
        self.done = False

    def read(self):
        for line in sys.stdin:
            if line.strip():
                with self.lock:
                    self.schedule = json.loads(line)
        self.done = True

    def at(self, t):
        with self.lock:
            s = self.schedule
        if s is None:
            return None, None
        if any(a <= t < b for a, b in s.get('pauses', [])):
            return s['names'], None
        w = s['waypoints']
        prev = w[0]
        for cur in w[1:]:
            if t < cur[0]:
                k = smooth((t - prev[0]) / max(1e-9, cur[0] - prev[0]))
                return s['names'], [a + k * (b - a) for a, b in zip(prev[1], cur[1])]
            prev = cur
        return s['names'], prev[1]


def main():
    rospy.init_node('joint_states_player', anonymous=True, disable_signals=True)
    pub = rospy.Publisher('/joint_states', JointState, queue_size=10)
    player = Player()
    threading.Thread(target=player.read, daemon=True).start()
    rate = rospy.Rate(RATE)
    while not player.done and not rospy.is_shutdown():
        now = rospy.Time.now()
        names, q = player.at(now.to_sec())
        if q is not None:
            msg = JointState()
            msg.header.stamp = now
            msg.name = names
            msg.position = q
            pub.publish(msg)
        rate.sleep()


if __name__ == '__main__':
    main()
