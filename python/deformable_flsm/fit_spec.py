"""What a fit (deformable_flsm.fit) fits: its spec (the recording, the scene, the tool, the
bounds), the package's config, and the recording and the markers or cloud it reads."""
import math
import os

import yaml

from deformable_flsm.fit_candidate import cloud_reference
from deformable_flsm.recording import Markers, Recording
from deformable_flsm.scene import load_params

#: what a fit may vary: the node's material parameters, and the tool's friction
FITTABLE = ("youngs_modulus", "poissons_ratio", "damping", "ambient_damping", "density", "friction")
# the observations of the object beside the tool's force: at most one is compared
OBSERVATIONS = ("markers", "markers_topic", "cloud", "cloud_topic")


class FitError(ValueError):
    """A fit that cannot start; the message says what to fix."""


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

