"""Scenes from the node's YAML files (what launch/flsm.launch loads as params and scene_params)."""
import os

import numpy as np
import yaml

from deformable_flsm import _core

ParamError = _core.ParamError


def load_params(*paths, **overrides):
    """The node's private parameters from YAML files and keyword overrides.

    Later files replace earlier ones key by key (as `rosparam load` of each into the node's
    namespace), then the overrides replace both. Raises ParamError for a file that is not a
    dictionary of parameters.
    """
    params = {}
    for path in paths:
        with open(path) as f:
            tree = yaml.safe_load(f) or {}
        if not isinstance(tree, dict):
            raise ParamError(f"{path}: the file must hold a dictionary of the node's parameters")
        params.update(tree)
    params.update(overrides)
    return params


class Simulation(_core.Simulation):
    """The scene flsm_node builds from the same private parameters, stepped from Python.

    Simulation(params) takes the parameters as a dict; Simulation.from_yaml(*paths, **overrides)
    reads them as the launch file does. Construction raises ParamError naming the parameter to
    fix, before anything is simulated.
    """

    @classmethod
    def from_yaml(cls, *paths, **overrides):
        source = ", ".join(os.path.basename(p) for p in paths) or "overrides"
        return cls(load_params(*paths, **overrides), source)

    def follow(self, collider, poses, times=None):
        """Moves `collider` through `poses` ((K, 3) positions or (K, 7) positions and quaternions
        [x, y, z, w]), one per time step from now, with the velocity that reaches the next pose
        at the next step; yields after each step (time, the collider's contact wrench)."""
        poses = np.asarray(poses, dtype=float)
        if poses.ndim != 2 or poses.shape[1] not in (3, 7):
            raise ValueError("poses must be (K, 3) positions or (K, 7) positions and [x, y, z, w]")
        if not np.all(np.isfinite(poses)):
            raise ValueError("poses must be finite")
        dt = self.time_step
        for k in range(len(poses)):
            p = poses[k]
            q = p[3:7] if p.shape[0] == 7 else np.array([0.0, 0.0, 0.0, 1.0])
            nxt = poses[min(k + 1, len(poses) - 1)]
            v = (nxt[:3] - p[:3]) / dt
            w = _angular_velocity(q, nxt[3:7] if nxt.shape[0] == 7 else q, dt)
            self.move_collider(collider, p[:3], q, v, w)
            self.step()
            yield self.time, self.contact_wrench(collider)


def _angular_velocity(q0, q1, dt):
    """The constant angular velocity (rad/s, world frame) that turns unit quaternion q0 into q1
    ([x, y, z, w]) in dt."""
    x0, y0, z0, w0 = q0
    x1, y1, z1, w1 = q1
    # q1 * conj(q0): the turn in the world frame
    w = w1 * w0 + x1 * x0 + y1 * y0 + z1 * z0
    v = np.array([x1 * w0 - w1 * x0 - y1 * z0 + z1 * y0,
                  y1 * w0 - w1 * y0 - z1 * x0 + x1 * z0,
                  z1 * w0 - w1 * z0 - x1 * y0 + y1 * x0])
    if w < 0:
        w, v = -w, -v
    s = np.linalg.norm(v)
    if s < 1e-12:
        return np.zeros(3)
    return v / s * (2.0 * np.arctan2(s, w) / dt)
