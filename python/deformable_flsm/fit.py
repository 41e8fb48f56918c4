"""Fit the simulated object's material to a recorded poke, each generation evaluated on Dask.

    ./scripts/flsm fit examples/fit/punch_fit.yaml [--scheduler tcp://HOST:8786] [--workers N]
    python3 -m deformable_flsm.fit SPEC.yaml [options]

Each evaluation builds the scene from its plain parameters (the node's YAML with the candidate's
values), replays the tool's recorded motion with the scene's tool collider and compares the force
on it with the recorded force. CMA-ES (python3-cmaes, ask and tell) searches two or more
parameters; one parameter is bracketed (a grid over the interval, narrowed around the best). A
checkpoint after each generation lets a stopped fit resume; a worker lost mid-fit costs its
evaluations (Dask runs them again elsewhere). docs/fit.md has the method and the figures.
"""
import argparse
import copy
import hashlib
import json
import math
import os
import pickle
import sys
import time

import numpy as np
import yaml

from deformable_flsm.recording import Markers, Recording, RecordingError
from deformable_flsm.scene import ParamError, Simulation, load_params
from deformable_flsm.search import Bracket, Cluster, Cma, Space  # noqa: F401 (also this module's API)

#: what a fit may vary: the node's material parameters, and the tool's friction
FITTABLE = ("youngs_modulus", "poissons_ratio", "damping", "ambient_damping", "density", "friction")
# the observations of the object beside the tool's force: at most one is compared
OBSERVATIONS = ("markers", "markers_topic", "cloud", "cloud_topic")


class FitError(ValueError):
    """A fit that cannot start; the message says what to fix."""


# --- the simulation of one candidate (runs on the workers) -------------------------------------

def scene_with(base, values, tool):
    """The scene's parameters with `values` applied (friction: the tool collider's)."""
    tree = copy.deepcopy(base)
    for name, value in values.items():
        if name == "friction":
            for c in tree.get("colliders", []):
                if isinstance(c, dict) and c.get("id") == tool:
                    c["static_friction"] = c["kinetic_friction"] = float(value)
        else:
            tree[name] = float(value)
    return tree


def tool_path(recording, dt, steps=None):
    """The tool's poses at the simulation's steps 0, dt, 2 dt, ... up to the recording's end (or
    `steps` steps, the last pose held beyond it): positions interpolated linearly, orientations
    normalised linearly (small turns a step)."""
    n = int(math.ceil(recording.times[-1] / dt - 1e-9)) if steps is None else steps
    ts = np.arange(n + 1) * dt
    out = np.column_stack([np.interp(ts, recording.times, recording.poses[:, j]) for j in range(7)])
    out[:, 3:] /= np.linalg.norm(out[:, 3:], axis=1, keepdims=True)
    return ts, out


def simulate(tree, recording, tool, markers=None):
    """The force on collider `tool` (N, (K, 3)) at the recording's times when it follows the
    recorded poses through the scene `tree` (the node's private parameters); with `markers`
    (recording.Markers, their times on the recording's clock from its start), also where the
    simulated object carries them at their times ((M, P, 3))."""
    sim = Simulation(tree, "the fit's scene")
    for name in sim.objects:
        info = sim.info(name)
        if info["stiffness_saturated"]:
            # the explicit step caps the modulus: any larger one would read the same
            raise ParamError("the explicit step caps youngs_modulus %.4g at these substeps (alpha %.3g "
                             "asked, %.3g used): set integrator: implicit (or auto), or more substeps"
                             % (tree.get("youngs_modulus", math.nan), info["requested_alpha"], info["alpha"]))
    if tool not in sim.colliders:
        raise ParamError(f"the scene has no collider '{tool}' (its colliders: {', '.join(sim.colliders)})")
    ts, poses = tool_path(recording, sim.time_step)
    forces = np.zeros((len(ts) + 1, 3))
    follow = sim.markers(markers.rest) if markers is not None else None
    carried = [follow.positions()] if follow is not None else None
    for k, (_, wrench) in enumerate(sim.follow(tool, poses)):
        forces[k + 1] = wrench["force"]
        if follow is not None:
            carried.append(follow.positions())
    # each the mean of the step's S sub-steps' forces, each at its sub-step's end: on average
    # dt (S + 1) / (2 S) after the step's start; compared with a recording of such means (the
    # node's) at the step's end, where the recording has it
    s = sim.substeps
    at = 1.0 if recording.step_means else (s + 1) / (2.0 * s)
    times = np.concatenate([[0.0], ts + sim.time_step * at])
    out = np.column_stack([np.interp(recording.times, times, forces[:, j]) for j in range(3)])
    if follow is None:
        return out
    # the state after each step, at its end; between steps interpolated
    ends = np.concatenate([[0.0], ts + sim.time_step])
    carried = np.stack(carried)
    flat = carried.reshape(len(ends), -1)
    at = np.column_stack([np.interp(markers.times, ends, flat[:, j]) for j in range(flat.shape[1])])
    return out, at.reshape(len(markers.times), -1, 3)


def evaluate(values, base, recording, tool, fit_mask, markers=None, marker_mask=None):
    """{cost, forces[, markers]} for one candidate: the RMS of the force error over the fit's
    samples relative to the RMS of the recorded force there; with markers, combined (root sum of
    squares) with the RMS of the markers' position error relative to the RMS of their recorded
    displacement. Cost inf when the scene refuses the candidate."""
    try:
        out = simulate(scene_with(base, values, tool), recording, tool, markers)
    except ParamError as e:
        return {"cost": math.inf, "forces": None, "error": str(e)}
    forces, carried = out if markers is not None else (out, None)
    force_cost = relative_rms(forces, recording.forces, fit_mask)
    marker_cost = marker_rms(carried, markers, marker_mask) if markers is not None else 0.0
    cost = math.hypot(force_cost, marker_cost)
    if not math.isfinite(cost):
        return {"cost": math.inf, "forces": None, "error": "the simulation diverged (a non-finite force)"}
    return {"cost": cost, "forces": forces, "markers": carried, "force_cost": force_cost,
            "marker_cost": marker_cost, "error": ""}


def marker_rms(carried, markers, mask):
    """Ordered markers: the RMS of their position error over the masked times, relative to the
    RMS of their recorded displacement from rest there. An unordered cloud: the RMS of the
    distances between the recorded cloud and the carried rest points along the surface's normals
    (cloud_residuals), relative to the same between the recorded cloud and the rest."""
    if not markers.ordered:
        error = np.mean(marker_errors(carried, markers, mask) ** 2)
    else:
        error = np.sum((carried[mask] - markers.positions[mask]) ** 2, axis=2).mean()
    scale = marker_scale(markers, mask)
    return math.sqrt(error / scale) if scale > 0 else math.sqrt(error)


def marker_errors(carried, markers, mask):
    """The carried markers' errors over the masked times, flat: ordered, each coordinate's; a
    cloud, its point-to-plane distances (cloud_residuals)."""
    if markers.ordered:
        return (carried[mask] - markers.positions[mask]).ravel()
    return cloud_reference(markers).residuals(carried[mask], np.flatnonzero(mask)).ravel()


def marker_scale(markers, mask):
    """The mean square the markers' errors are taken relative to: of their recorded displacement
    from rest (ordered, per marker), of the rest's distances from each recorded cloud (a cloud)."""
    if markers.ordered:
        return np.sum((markers.positions[mask] - markers.rest) ** 2, axis=2).mean()
    frames = np.flatnonzero(mask)
    rest = np.broadcast_to(markers.rest, (len(frames),) + markers.rest.shape)
    return np.mean(cloud_reference(markers).residuals(rest, frames) ** 2)


def nearest(a, b):
    """For each point of a (N, 3), the index of its nearest point of b (K, 3)."""
    d2 = np.sum(a * a, axis=1)[:, None] - 2.0 * (a @ b.T) + np.sum(b * b, axis=1)[None, :]
    return np.argmin(d2, axis=1)


def surface_normals(points, neighbours):
    """Unit normals (P, 3) of a surface sampled by points (P, 3), turned away from the points'
    centroid, and how far from flat each point's neighbourhood (indices (P, k)) is: the least of
    its spread's three variances over their sum (0 on a plane, 1/3 for a ball of points)."""
    near = points[neighbours]
    d = near - near.mean(axis=1, keepdims=True)
    values, vectors = np.linalg.eigh(np.einsum("pki,pkj->pij", d, d))
    n = vectors[:, :, 0]
    n *= np.where(np.sum(n * (points - points.mean(axis=0)), axis=1) < 0.0, -1.0, 1.0)[:, None]
    return n, values[:, 0] / np.maximum(values.sum(axis=1), 1e-300)


#: neighbours of a point for its normal; the flatness (surface_normals) below which a point is
#: on a face (above it, on an edge or a corner, where no one normal holds), raised to three times
#: the cloud's median flatness for a noisy cloud; the least cosine between the normals of a pair
CLOUD_NEIGHBOURS, CLOUD_FLAT, CLOUD_COSINE = 12, 0.002, 0.9


def _neighbours(points):
    d2 = np.sum((points[:, None, :] - points[None, :, :]) ** 2, axis=2)
    return np.argsort(d2, axis=1)[:, :CLOUD_NEIGHBOURS]


def _on_a_face(flatness):
    return flatness < max(CLOUD_FLAT, 3.0 * float(np.median(flatness)))


class CloudReference:
    """What comparing a recorded cloud with the carried rest points needs that no candidate
    changes: the rest's neighbours and which of its points lie on a face, each recorded frame's
    normals and which of its points lie on a face. Made once for a fit (load_markers), not in
    every evaluation."""

    def __init__(self, rest, recorded):
        self.neighbours = _neighbours(rest)
        self.face = _on_a_face(surface_normals(rest, self.neighbours)[1])
        self.recorded = np.asarray(recorded)
        self.normals, self.faces = [], []
        for r in self.recorded:
            n, flatness = surface_normals(r, _neighbours(r))
            self.normals.append(n)
            self.faces.append(_on_a_face(flatness))

    def residuals(self, simulated, frames):
        """cloud_residuals of the simulated clouds ((len(frames), P, 3)) against the recorded
        frames of those indices."""
        out = []
        for c, k in zip(simulated, frames):
            r, nr, face_r = self.recorded[k], self.normals[k], self.faces[k]
            n, _ = surface_normals(c, self.neighbours)
            j = nearest(r, c)
            keep = self.face[j] & face_r & (np.abs(np.sum(nr * n[j], axis=1)) >= CLOUD_COSINE)
            out.append(np.where(keep, np.sum((r - c[j]) * n[j], axis=1), 0.0))
            i = nearest(c, r)
            keep = self.face & face_r[i] & (np.abs(np.sum(nr[i] * n, axis=1)) >= CLOUD_COSINE)
            out.append(np.where(keep, np.sum((r[i] - c) * n, axis=1), 0.0))
        return np.concatenate(out)


def cloud_residuals(simulated, recorded, rest):
    """For clouds at the same times ((M, P, 3) each), the simulated being the rest points (P, 3)
    carried by the simulation: every recorded point's distance from the nearest simulated point
    along that point's surface normal, and every simulated point's from the nearest recorded one
    along its own normal, all times together (2 M P,), signed (m). Point to plane, as in ICP: a
    recorded point on the simulated surface between its sampled points counts zero, whatever
    points either cloud happened to sample. A pair counts zero where either point is on an edge or
    a corner (of the rest, of the recorded cloud) or their normals differ by more than 25 degrees:
    there a point's nearest may lie on another face."""
    return CloudReference(rest, recorded).residuals(simulated, range(len(recorded)))


def cloud_reference(markers):
    """The CloudReference of an unordered cloud (recording.Markers), made at its first use and
    kept with it (sent to the workers with it)."""
    if getattr(markers, "cloud_reference", None) is None:
        markers.cloud_reference = CloudReference(markers.rest, markers.positions)
    return markers.cloud_reference


def relative_rms(simulated, measured, mask):
    error = np.sum((simulated[mask] - measured[mask]) ** 2, axis=1).mean()
    scale = np.sum(measured[mask] ** 2, axis=1).mean()
    return math.sqrt(error / scale) if scale > 0 else math.sqrt(error)


# --- the fit -------------------------------------------------------------------------------------

class FitSpec:
    """What to fit: the recording (and optionally markers on the object: recording.Markers), the
    scene (files over the node's config/flsm.yaml), the tool collider, the parameters and their
    bounds, the held-out share of the recording."""

    def __init__(self, recording, scene, tool, bounds, holdout=0.25, generations=30, population=0,
                 seed=1, base=None, markers=None, markers_topic=None, frame_id="world", cloud=None,
                 cloud_topic=None, cloud_box=None, cloud_points=600):
        self.recording = recording
        self.markers = markers
        self.markers_topic = markers_topic
        self.cloud = cloud
        self.cloud_topic = cloud_topic
        self.cloud_box = cloud_box
        self.cloud_points = int(cloud_points)
        self.frame_id = frame_id
        self.scene_files = list(scene)
        self.tool = tool
        self.bounds = dict(bounds)
        self.holdout = float(holdout)
        self.generations = int(generations)
        self.population = int(population)
        self.seed = int(seed)
        self.base_file = base or package_config()
        self.validate()

    @classmethod
    def from_yaml(cls, path, **overrides):
        with open(path) as f:
            spec = yaml.safe_load(f)
        if not isinstance(spec, dict):
            raise FitError(f"{path}: a fit spec is a dictionary (recording, scene, tool, fit)")
        here = os.path.dirname(os.path.abspath(path))
        rel = lambda p: p if os.path.isabs(p) else os.path.join(here, p)  # noqa: E731
        scene = spec.get("scene", [])
        scene = [scene] if isinstance(scene, str) else scene
        args = dict(recording=rel(spec["recording"]) if "recording" in spec else None,
                    markers=rel(spec["markers"]) if spec.get("markers") else None,
                    markers_topic=spec.get("markers_topic"), frame_id=spec.get("frame_id", "world"),
                    cloud=rel(spec["cloud"]) if spec.get("cloud") else None,
                    cloud_topic=spec.get("cloud_topic"), cloud_box=spec.get("cloud_box"),
                    cloud_points=spec.get("cloud_points", 600),
                    scene=[rel(s) for s in scene], tool=spec.get("tool"), bounds=spec.get("fit", {}),
                    holdout=spec.get("holdout", 0.25), generations=spec.get("generations", 30),
                    population=spec.get("population", 0), seed=spec.get("seed", 1))
        overrides = {k: v for k, v in overrides.items() if v is not None}
        if any(k in overrides for k in OBSERVATIONS):
            for k in OBSERVATIONS:  # a source given here replaces the file's, as a command line flag does
                args[k] = None
        args.update(overrides)
        return cls(**args)

    def validate(self):
        if not self.recording:
            raise FitError("no recording: give a CSV (time, x, y, z, fx, fy, fz) or a bag")
        if not self.tool:
            raise FitError("no tool: name the scene's collider that follows the recorded tool")
        if not self.bounds:
            raise FitError(f"nothing to fit: give bounds for any of {', '.join(FITTABLE)}")
        for name, b in self.bounds.items():
            if name not in FITTABLE:
                raise FitError(f"'{name}' cannot be fitted: it must be one of {', '.join(FITTABLE)}")
            ok = isinstance(b, (list, tuple)) and len(b) == 2 and all(isinstance(v, (int, float)) for v in b)
            if not ok:
                raise FitError(f"the bounds of '{name}' are {b!r}: give two numbers [low, high] (YAML reads "
                               "2e3 as a string: write 2.0e+3 or 2000.0)")
            if not (math.isfinite(b[0]) and math.isfinite(b[1]) and b[0] < b[1]):
                raise FitError(f"the bounds of '{name}' are {b}: give [low, high] with low < high")
        if not 0.0 <= self.holdout < 0.9:
            raise FitError(f"holdout {self.holdout}: the held-out share must be in [0, 0.9)")
        if self.generations < 1:
            raise FitError("generations must be 1 or more")
        if sum(bool(getattr(self, k)) for k in OBSERVATIONS) > 1:
            raise FitError("give one of markers, markers_topic, cloud and cloud_topic")
        box = self.cloud_box
        if box is not None and not (isinstance(box, (list, tuple)) and len(box) == 6
                                    and all(isinstance(v, (int, float)) and math.isfinite(v) for v in box)
                                    and all(box[k] < box[k + 3] for k in range(3))):
            raise FitError(f"cloud_box {box!r}: give [x0, y0, z0, x1, y1, z1] (m, the simulation frame) "
                           "with x0 < x1, y0 < y1, z0 < z1")
        if not 10 <= self.cloud_points <= 20000:
            raise FitError(f"cloud_points {self.cloud_points}: sample 10 to 20000 points of each cloud")

    def base_tree(self):
        tree = load_params(self.base_file, *self.scene_files)
        tree.setdefault("threads", 1)  # the workers run in parallel: one core each
        return tree


def package_config():
    """config/flsm.yaml of the package (as launch/flsm.launch loads it)."""
    here = os.path.dirname(os.path.abspath(__file__))
    source = os.path.join(here, "..", "..", "config", "flsm.yaml")
    if os.path.isfile(source):
        return os.path.normpath(source)
    import rospkg
    return os.path.join(rospkg.RosPack().get_path("deformable_flsm"), "config", "flsm.yaml")


def load_recording(spec, tool_frame=None, wrench_topic=None, frame_id="world"):
    """The spec's recording; a bag's wrenches from a WrenchStamped topic or from the node's
    ~contact_wrenches (the entry of the spec's tool collider)."""
    path = spec.recording
    if not os.path.isfile(path):
        raise FitError(f"the recording {path} does not exist")
    if path.endswith(".bag"):
        if not tool_frame or not wrench_topic:
            raise FitError("a bag needs --tool-frame (the tool's tf frame) and --wrench-topic "
                           "(its geometry_msgs/WrenchStamped, or the node's ~contact_wrenches)")
        return Recording.from_bag(path, tool_frame, wrench_topic, frame_id, collider=spec.tool)
    return Recording.from_csv(path)


def _key(spec, base, recording, markers):
    h = hashlib.sha256()
    h.update(json.dumps([base, spec.tool, spec.bounds, spec.holdout, spec.seed, spec.population],
                        sort_keys=True, default=str).encode())
    arrays = [recording.times, recording.poses, recording.forces]
    if markers is not None:
        arrays += [markers.times, markers.positions]
    for a in arrays:
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()


def load_markers(spec, recording):
    """The spec's markers or cloud (None without), their times on the recording's clock from its
    start: a CSV, or a PointCloud2 topic of the recording's bag (markers_topic: the node's
    ~particles; cloud_topic: a depth camera's points, cropped to cloud_box)."""
    if spec.cloud_topic:
        if not spec.recording.endswith(".bag"):
            raise FitError("cloud_topic needs the recording to be a bag")
        m = Markers.cloud_from_bag(spec.recording, spec.cloud_topic, spec.frame_id, recording.start,
                                   recording.start + recording.times[-1], points=spec.cloud_points,
                                   box=spec.cloud_box, seed=spec.seed)
        cloud_reference(m)  # once, before the evaluations take it to the workers
        return m
    if spec.cloud:
        if not os.path.isfile(spec.cloud):
            raise FitError(f"the cloud {spec.cloud} does not exist")
        m = Markers.cloud_from_csv(spec.cloud, points=spec.cloud_points, box=spec.cloud_box, seed=spec.seed)
        cloud_reference(m)  # once, before the evaluations take it to the workers
        return _on_the_recordings_clock(m, recording, spec.cloud)
    if spec.markers_topic:
        if not spec.recording.endswith(".bag"):
            raise FitError("markers_topic needs the recording to be a bag")
        return Markers.from_bag(spec.recording, spec.markers_topic, spec.frame_id, recording.start,
                                recording.start + recording.times[-1])
    if not spec.markers:
        return None
    if not os.path.isfile(spec.markers):
        raise FitError(f"the markers {spec.markers} do not exist")
    return _on_the_recordings_clock(Markers.from_csv(spec.markers), recording, spec.markers)


def _on_the_recordings_clock(m, recording, path):
    m.times = m.times - recording.start
    if m.times[0] < -1e-9 or m.times[-1] > recording.times[-1] + 1e-9:
        raise FitError(f"{path}: its times must lie within the recording's "
                       f"(0 to {recording.times[-1]:.3f} s from its start)")
    return m


def _save(path, state):
    tmp = path + ".tmp"
    with open(tmp, "wb") as f:
        pickle.dump(state, f)
    os.replace(tmp, path)


def _bar(done, total, width=24):
    n = int(round(width * done / total))
    return "[" + "#" * n + "-" * (width - n) + "]"


def _check_scene(spec, base, space, log):
    """The scene built once before any generation: a scene it refuses stops the fit."""
    try:
        check = Simulation(scene_with(base, space.values(np.full(len(space.names), 0.5)), spec.tool),
                           "the fit's scene")
    except ParamError as e:
        raise FitError(f"the scene cannot be built: {e}") from None
    if spec.tool not in check.colliders:
        raise FitError(f"the scene has no collider '{spec.tool}' (it has: {', '.join(check.colliders) or 'none'})")
    if check.unknown_params:
        log(f"fit: not parameters of the node (misspelt?): {', '.join(check.unknown_params)}")


def _start_or_resume(spec, space, key, checkpoint, log):
    """The search's state: the checkpoint's when it is of this fit, else a new one."""
    if os.path.isfile(checkpoint):
        with open(checkpoint, "rb") as f:
            state = pickle.load(f)
        if state.get("key") == key:
            log("fit: resuming after generation %d" % state["generation"])
            return state
        log("fit: the checkpoint in %s is of another fit: starting anew" % os.path.dirname(checkpoint))
    dims = len(space.names)
    population = spec.population or (4 + int(3 * math.log(dims)) if dims > 1 else 8)
    search = Cma(dims, population, spec.seed) if dims > 1 else Bracket(population)
    return {"key": key, "generation": 0, "search": search, "history": [], "best": None,
            "evaluations": 0, "seconds": 0.0, "refused": 0, "refusal": ""}


def _generation(state, space, cluster, problem, spec, checkpoint, log):
    """One generation evaluated on the cluster, told to the search, saved."""
    t0 = time.time()
    search = state["search"]
    points = search.ask_all()
    results = cluster.map(evaluate, [space.values(u) for u in points], **problem)
    costs = [r["cost"] for r in results]
    search.tell(points, costs)
    k = int(np.argmin(costs))
    if state["best"] is None or costs[k] < state["best"]["cost"]:
        state["best"] = _as_best(space.values(points[k]), results[k])
    state["generation"] += 1
    state["evaluations"] += len(points)
    state["seconds"] += time.time() - t0
    state["history"].append((state["generation"], costs))
    refused = [r["error"] for r in results if r["error"]]
    if refused:
        state["refused"] += len(refused)
        state["refusal"] = refused[0]
    _save(checkpoint, state)
    best = state["best"]
    log("fit: generation %d/%d %s best %.4f %s (%d evaluations, %.1f s)" % (
        state["generation"], spec.generations, _bar(state["generation"], spec.generations),
        best["cost"], " ".join("%s=%.4g" % kv for kv in best["values"].items()), len(points), time.time() - t0))
    if not math.isfinite(best["cost"]):
        raise FitError("the scene refused every candidate: " + refused[0])


def residual_vector(res, recording, mask, markers=None, marker_mask=None, mscale=None):
    """The candidate's errors as one vector whose norm is its cost: the force errors over the fit's
    samples scaled as relative_rms() scales them, then the markers' as marker_rms() does (mscale:
    marker_scale(), when the caller has it)."""
    count = max(1, int(np.count_nonzero(mask)))
    scale = np.sum(recording.forces[mask] ** 2, axis=1).mean()
    out = (res["forces"][mask] - recording.forces[mask]).ravel() / math.sqrt(count * (scale if scale > 0 else 1.0))
    if markers is None:
        return out
    error = marker_errors(res["markers"], markers, marker_mask)
    scale = marker_scale(markers, marker_mask) if mscale is None else mscale
    count = error.size // 3 if markers.ordered else error.size  # markers at their times, or cloud points
    return np.concatenate([out, error / math.sqrt(max(1, count) * (scale if scale > 0 else 1.0))])


#: the refinement after the search: at most this many Levenberg-Marquardt iterations, each its
#: Jacobian by central differences of this step in the unit cube, and these damping factors tried
#: at once; it stops when an iteration lowers the cost by less than this fraction
REFINE_ITERATIONS = 8
REFINE_STEP = 0.002
REFINE_LAMBDAS = (1e-4, 1e-2, 1.0)
REFINE_GAIN = 1e-3


def refine(best, space, cluster, problem, log):
    """Levenberg-Marquardt from the search's best, in the unit cube: the search finds the valley,
    this follows its floor where a weakly determined parameter (a damping, seen only in how a
    tap's ringing decays) leaves CMA-ES's steps small. Each iteration evaluates the 2n probes of
    the Jacobian, then one candidate per damping factor, all on the cluster; only a lower cost
    is taken. Returns {best, evaluations, seconds}."""
    recording, mask = problem["recording"], problem["fit_mask"]
    markers, marker_mask = problem["markers"], problem["marker_mask"]
    mscale = marker_scale(markers, marker_mask) if markers is not None else None
    n = len(space.names)
    evaluations, seconds = 0, 0.0
    for it in range(REFINE_ITERATIONS):
        t0 = time.time()
        u = space.unit(best["values"])
        probes = []
        for i in range(n):
            for sign in (+1, -1):
                v = u.copy()
                v[i] = np.clip(v[i] + sign * REFINE_STEP, 0.0, 1.0)
                probes.append(v)
        results = cluster.map(evaluate, [space.values(v) for v in probes], **problem)
        evaluations += len(probes)
        if any(r["forces"] is None for r in results):
            break
        r0 = residual_vector(best, recording, mask, markers, marker_mask, mscale)
        J = np.column_stack([(residual_vector(results[2 * i], recording, mask, markers, marker_mask, mscale) -
                              residual_vector(results[2 * i + 1], recording, mask, markers, marker_mask, mscale)) /
                             (probes[2 * i][i] - probes[2 * i + 1][i]) for i in range(n)])
        A, g = J.T @ J, J.T @ r0
        steps = []
        for lam in REFINE_LAMBDAS:
            try:
                steps.append(np.clip(u - np.linalg.solve(A + lam * np.diag(np.diag(A) + 1e-12), g), 0.0, 1.0))
            except np.linalg.LinAlgError:
                pass
        tried = cluster.map(evaluate, [space.values(v) for v in steps], **problem)
        evaluations += len(steps)
        seconds += time.time() - t0
        k = int(np.argmin([r["cost"] for r in tried])) if tried else 0
        if not tried or not tried[k]["cost"] < best["cost"]:
            break
        gain = 1.0 - tried[k]["cost"] / best["cost"]
        best = _as_best(space.values(steps[k]), tried[k])
        log("fit: refined %d: %.4f %s (%d evaluations, %.1f s)" % (
            it + 1, best["cost"], " ".join("%s=%.4g" % kv for kv in best["values"].items()),
            len(probes) + len(steps), time.time() - t0))
        if gain < REFINE_GAIN:
            break
    return {"best": best, "evaluations": evaluations, "seconds": seconds}


def _as_best(values, result):
    return {"values": values, "cost": result["cost"], "forces": result["forces"], "markers": result.get("markers"),
            "force_cost": result.get("force_cost"), "marker_cost": result.get("marker_cost")}


def fit(spec, out_dir, cluster=None, recording=None, log=print):
    """Runs (or resumes) the fit; returns the result dict written to out_dir/report.yaml."""
    recording = recording or load_recording(spec)
    base = spec.base_tree()
    space = Space(spec.bounds)
    cut = recording.times[-1] * (1.0 - spec.holdout) + 1e-12
    mask = recording.times <= cut
    held = ~mask
    markers = load_markers(spec, recording)
    marker_mask = markers.times <= cut if markers is not None else None
    _check_scene(spec, base, space, log)
    os.makedirs(out_dir, exist_ok=True)
    checkpoint = os.path.join(out_dir, "checkpoint.pkl")
    state = _start_or_resume(spec, space, _key(spec, base, recording, markers), checkpoint, log)
    problem = dict(base=base, recording=recording, tool=spec.tool, fit_mask=mask, markers=markers,
                   marker_mask=marker_mask)
    own = cluster is None
    cluster = cluster or Cluster()
    try:
        while state["generation"] < spec.generations and not state["search"].should_stop():
            _generation(state, space, cluster, problem, spec, checkpoint, log)
        # the refinement of the search's best, again when the search went on since
        refined = state.get("refined")
        if refined is None or refined["generation"] != state["generation"]:
            refined = dict(refine(state["best"], space, cluster, problem, log), generation=state["generation"])
            state["refined"] = refined
            _save(checkpoint, state)
        best = refined["best"]
        sigma = uncertainty(cluster, best, base, recording, spec.tool, mask, markers, marker_mask)
    finally:
        if own:
            cluster.close()
    at_bound = [n for n, x in zip(space.names, space.unit(best["values"])) if x <= 0.01 or x >= 0.99]
    if at_bound:
        log("fit: %s ended at a bound: widen the bounds, or the scene cannot match the recording"
            % ", ".join(at_bound))
    if state["refused"]:
        log("fit: %d candidates refused, e.g.: %s" % (state["refused"], state["refusal"]))
    # a standard error of half the value or more: the recording does not tell this parameter
    vague = [n for n in space.names if not sigma[n] < 0.5 * abs(best["values"][n])]
    if vague:
        log("fit: the recording does not determine %s (standard error half its value or more): "
            "fix it in the scene, or record a motion it changes" % ", ".join(vague))
    result = {
        "parameters": {n: float(v) for n, v in best["values"].items()},
        "standard_error": {n: float(s) for n, s in sigma.items()},
        "cost": float(best["cost"]),
        "force_cost": float(best.get("force_cost") or best["cost"]),
        "held_out_cost": float(relative_rms(best["forces"], recording.forces, held)) if held.any() else None,
        "marker_cost": float(best["marker_cost"]) if markers is not None else None,
        "held_out_marker_cost": (float(marker_rms(best["markers"], markers, ~marker_mask))
                                 if markers is not None and (~marker_mask).any() else None),
        "generations": state["generation"],
        "evaluations": state["evaluations"] + refined["evaluations"],
        "refine_evaluations": refined["evaluations"],
        "seconds": round(state["seconds"] + refined["seconds"], 2),
        "at_bound": at_bound,
        "not_determined": vague,
        "refused": state["refused"],
        "recording": recording.source,
        "held_out_from": float(recording.times[held][0]) if held.any() else None,
    }
    write_outputs(out_dir, spec, result, recording, best["forces"], mask,
                  (markers, best.get("markers")) if markers is not None else None)
    return result


def uncertainty(cluster, best, base, recording, tool, mask, markers=None, marker_mask=None):
    """Standard errors from the residuals' Jacobian at the optimum (central differences of 1 %):
    s^2 (J^T J)^-1 with s^2 the residuals' variance; the noise's share of the error only, not the
    model's."""
    names = list(best["values"])
    x = np.array([best["values"][n] for n in names])
    h = np.where(x != 0.0, 0.01 * np.abs(x), 1e-3)
    probes = []
    for i in range(len(names)):
        for sign in (+1, -1):
            v = x.copy()
            v[i] += sign * h[i]
            probes.append(dict(zip(names, v.tolist())))
    results = cluster.map(evaluate, probes, base=base, recording=recording, tool=tool, fit_mask=mask,
                          markers=markers, marker_mask=marker_mask)
    if any(r["forces"] is None for r in results):
        return {n: math.nan for n in names}
    # the residuals in the cost's units: the force along the recorded force's mean direction (one
    # a sample: the other components of a poke are mostly zero and would count as degrees of
    # freedom they are not) over its RMS, the markers' coordinates over their displacement's RMS
    axis = recording.forces[mask].mean(axis=0)
    axis = axis / np.linalg.norm(axis) if np.linalg.norm(axis) > 0 else np.array([0.0, 0.0, 1.0])
    fscale = math.sqrt(np.sum(recording.forces[mask] ** 2, axis=1).mean()) or 1.0

    mscale = (math.sqrt(marker_scale(markers, marker_mask)) or 1.0) if markers is not None else 1.0

    def residual(res):
        out = (res["forces"][mask] - recording.forces[mask]) @ axis / fscale
        if markers is not None:
            out = np.concatenate([out, marker_errors(res["markers"], markers, marker_mask) / mscale])
        return out

    J = np.column_stack([(residual(results[2 * i]) - residual(results[2 * i + 1])) / (2 * h[i])
                         for i in range(len(names))])
    r = residual(best)
    dof = max(1, r.size - len(names))
    try:
        cov = np.linalg.inv(J.T @ J) * (r @ r) / dof
    except np.linalg.LinAlgError:
        return {n: math.inf for n in names}
    return {n: math.sqrt(max(0.0, cov[i, i])) for i, n in enumerate(names)}


def write_outputs(out_dir, spec, result, recording, forces, mask, markers=None):
    """fitted.yaml (the scene with the fitted values: the node's scene_params), report.yaml and
    fit.png (force against depth and time, with the residuals)."""
    scene = load_params(*spec.scene_files) if spec.scene_files else {}
    scene = scene_with(scene, result["parameters"], spec.tool)
    with open(os.path.join(out_dir, "fitted.yaml"), "w") as f:
        f.write("# The scene with its material fitted by deformable_flsm.fit to %s\n" % recording.source)
        f.write("# (%s); run: roslaunch deformable_flsm flsm.launch scene_params:=%s\n" % (
            ", ".join("%s %.4g +- %.2g" % (n, v, result["standard_error"][n])
                      for n, v in result["parameters"].items()),
            os.path.join(os.path.abspath(out_dir), "fitted.yaml")))
        yaml.safe_dump(scene, f, default_flow_style=None, sort_keys=False)
    with open(os.path.join(out_dir, "report.yaml"), "w") as f:
        yaml.safe_dump(result, f, sort_keys=False)
    plot(os.path.join(out_dir, "fit.png"), recording, forces, mask, result, markers)


def plot(path, recording, forces, mask, result, markers=None):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    axis = -recording.forces.mean(axis=0)
    axis = axis / np.linalg.norm(axis) if np.linalg.norm(axis) > 0 else np.array([0.0, 0.0, -1.0])
    measured, fitted = -recording.forces @ axis, -forces @ axis
    depth = 1e3 * recording.depth
    fig, ax = plt.subplots(4 if markers else 3, 1, figsize=(7, 12 if markers else 9))
    ax[0].plot(depth[mask], measured[mask], ".", ms=3, label="recorded (fitted)")
    ax[0].plot(depth[~mask], measured[~mask], ".", ms=3, color="grey", label="recorded (held out)")
    ax[0].plot(depth, fitted, "-", label="simulated, fitted")
    ax[0].set_xlabel("depth (mm)")
    ax[0].set_ylabel("force (N)")
    ax[0].legend()
    ax[0].set_title(", ".join("%s %.4g" % kv for kv in result["parameters"].items()))
    ax[1].plot(recording.times, measured, ".", ms=3, label="recorded")
    ax[1].plot(recording.times, fitted, "-", label="simulated")
    if (~mask).any():
        ax[1].axvspan(recording.times[~mask][0], recording.times[-1], color="grey", alpha=0.15, label="held out")
    ax[1].set_xlabel("time (s)")
    ax[1].set_ylabel("force (N)")
    ax[1].legend()
    ax[2].plot(recording.times, fitted - measured, ".", ms=3)
    ax[2].axhline(0.0, color="k", lw=0.5)
    ax[2].set_xlabel("time (s)")
    ax[2].set_ylabel("residual (N)")
    if markers and not markers[0].ordered:
        m, carried = markers
        reference = cloud_reference(m)
        rms = lambda a: np.array([1e3 * math.sqrt(np.mean(reference.residuals(a[k:k + 1], [k]) ** 2))  # noqa: E731
                                  for k in range(len(m.times))])
        ax[3].plot(m.times, rms(np.broadcast_to(m.rest, m.positions.shape)), ".", ms=4,
                   label="recorded cloud from the rest")
        ax[3].plot(m.times, rms(carried), "-", label="recorded cloud from the simulated")
        ax[3].set_xlabel("time (s)")
        ax[3].set_ylabel("RMS distance along the normals (mm)")
        ax[3].legend(fontsize="small")
    elif markers:
        m, carried = markers
        for k, name in ((0, "x"), (1, "y"), (2, "z")):
            ax[3].plot(m.times, 1e3 * np.sqrt(np.mean((m.positions[:, :, k] - m.rest[:, k]) ** 2, axis=1)), ".",
                       ms=4, color="C%d" % k, label="recorded, %s" % name)
            ax[3].plot(m.times, 1e3 * np.sqrt(np.mean((carried[:, :, k] - m.rest[:, k]) ** 2, axis=1)), "-",
                       color="C%d" % k, label="simulated, %s" % name)
        ax[3].set_xlabel("time (s)")
        ax[3].set_ylabel("markers' RMS displacement (mm)")
        ax[3].legend(ncol=3, fontsize="small")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None):
    parser = argparse.ArgumentParser(prog="flsm fit", description=__doc__.split("\n\n")[0])
    parser.add_argument("spec", help="the fit's YAML: recording, scene, tool, fit: {name: [low, high]}")
    parser.add_argument("--recording", help="a CSV (time, x, y, z[, qx, qy, qz, qw], fx, fy, fz) or a bag")
    parser.add_argument("--tool-frame", help="(bag) the tool's tf frame")
    parser.add_argument("--wrench-topic", help="(bag) the tool's geometry_msgs/WrenchStamped topic")
    parser.add_argument("--frame-id", help="(bag) the simulation frame (default world)")
    parser.add_argument("--markers-topic", help="(bag) a PointCloud2 of the same points in every message "
                                                "(the node's ~particles) to follow as markers")
    parser.add_argument("--cloud-topic", help="(bag) a PointCloud2 of the object from a depth camera "
                                              "(any points, any order) to compare point to plane")
    parser.add_argument("--cloud-box", type=float, nargs=6, metavar=("X0", "Y0", "Z0", "X1", "Y1", "Z1"),
                        help="crop the cloud to this box (m, the simulation frame): the object only")
    parser.add_argument("--scheduler", help="a Dask scheduler (tcp://HOST:8786); default: a local cluster")
    parser.add_argument("--workers", type=int, help="local cluster's worker processes (default: the cores)")
    parser.add_argument("--generations", type=int)
    parser.add_argument("--seed", type=int)
    parser.add_argument("--out", default="fit_out", help="output directory (default fit_out)")
    args = parser.parse_args(argv)
    try:
        spec = FitSpec.from_yaml(args.spec, recording=args.recording, generations=args.generations, seed=args.seed,
                                 markers_topic=args.markers_topic, frame_id=args.frame_id,
                                 cloud_topic=args.cloud_topic, cloud_box=args.cloud_box)
        recording = load_recording(spec, args.tool_frame, args.wrench_topic, spec.frame_id)
        cluster = Cluster(args.scheduler, args.workers)
        try:
            result = fit(spec, args.out, cluster, recording,
                         log=lambda m: print(m, file=sys.stderr, flush=True))
        finally:
            cluster.close()
    except (FitError, RecordingError, ParamError, OSError) as e:
        print("flsm fit: %s" % e, file=sys.stderr)
        return 2
    print(yaml.safe_dump(result, sort_keys=False), end="")
    print("flsm fit: wrote %s/fitted.yaml, report.yaml, fit.png" % args.out, file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
