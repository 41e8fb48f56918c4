"""A recorded poke: the tool's pose and the force on it over time, from a CSV file or a bag."""
import csv

import numpy as np


class RecordingError(ValueError):
    """A recording that cannot be used; the message says what to fix."""


class Recording:
    """times (K,) s from the recording's start; poses (K, 7): position (m) and orientation
    [x, y, z, w] of the tool's frame in the simulation frame; forces (K, 3): the force the object
    exerts on the tool (N, simulation frame). step_means: each force is the mean over the
    simulation step that ends at its time (the node's ~contact_wrenches), not a sample at that
    time (a wrist sensor's)."""

    def __init__(self, times, poses, forces, source="recording", step_means=False):
        self.times = np.asarray(times, dtype=float)
        self.poses = np.asarray(poses, dtype=float)
        self.forces = np.asarray(forces, dtype=float)
        self.source = source
        self.step_means = bool(step_means)
        k = len(self.times)
        if k < 3:
            raise RecordingError(f"{source}: {k} samples; a fit needs at least 3")
        if self.poses.shape != (k, 7) or self.forces.shape != (k, 3):
            raise RecordingError(f"{source}: poses must be (K, 7) and forces (K, 3) for K = {k} times")
        for name, a in (("times", self.times), ("poses", self.poses), ("forces", self.forces)):
            if not np.all(np.isfinite(a)):
                raise RecordingError(f"{source}: its {name} are not all finite")
        if np.any(np.diff(self.times) <= 0.0):
            raise RecordingError(f"{source}: its times must increase")
        norms = np.linalg.norm(self.poses[:, 3:], axis=1)
        if np.any(np.abs(norms - 1.0) > 1e-3):
            raise RecordingError(f"{source}: its orientations must be unit quaternions [x, y, z, w]")
        # q and -q are one turn: made continuous, so that interpolating between samples is safe
        for i in range(1, k):
            if np.dot(self.poses[i, 3:], self.poses[i - 1, 3:]) < 0.0:
                self.poses[i, 3:] *= -1.0
        self.start = float(self.times[0])  # the recording's clock at its first sample
        self.times = self.times - self.times[0]

    @property
    def depth(self):
        """How far the tool has moved along the mean force's opposite since the start (m): the
        indentation for a poke."""
        axis = -self.forces.mean(axis=0)
        n = np.linalg.norm(axis)
        axis = axis / n if n > 0 else np.array([0.0, 0.0, -1.0])
        return (self.poses[:, :3] - self.poses[0, :3]) @ axis

    @classmethod
    def from_csv(cls, path, forces=True):
        """Columns by header: time, x, y, z, optionally qx, qy, qz, qw, then fx, fy, fz (zero when
        `forces` is False: a tool path); lines starting with # are comments."""
        header, rows = _read_csv(path)
        if not header:
            raise RecordingError(f"{path}: empty")
        need = ["time", "x", "y", "z"] + (["fx", "fy", "fz"] if forces else [])
        missing = [h for h in need if h not in header]
        if missing:
            raise RecordingError(f"{path}: the header has no column {', '.join(missing)} "
                                 f"(it needs {', '.join(need)}, optionally qx, qy, qz, qw)")
        data = _numbers(path, rows)
        if data.ndim != 2 or data.shape[1] != len(header):
            raise RecordingError(f"{path}: every row must have the header's {len(header)} columns")
        col = {h: data[:, header.index(h)] for h in header}
        quat = (np.column_stack([col[q] for q in ("qx", "qy", "qz", "qw")])
                if all(q in col for q in ("qx", "qy", "qz", "qw"))
                else np.tile([0.0, 0.0, 0.0, 1.0], (len(data), 1)))
        poses = np.column_stack([col["x"], col["y"], col["z"], quat])
        force = (np.column_stack([col["fx"], col["fy"], col["fz"]]) if forces
                 else np.zeros((len(data), 3)))
        return cls(col["time"], poses, force, path)

    def to_csv(self, path):
        with open(path, "w") as f:
            f.write("time,x,y,z,qx,qy,qz,qw,fx,fy,fz\n")
            for t, p, w in zip(self.times, self.poses, self.forces):
                f.write(",".join("%.9g" % v for v in (t, *p, *w)) + "\n")

    @classmethod
    def from_bag(cls, path, tool_frame, wrench_topic, frame_id="world", collider=None):
        """The tool frame's pose in `frame_id` from the bag's /tf and /tf_static (interpolated)
        at each message of `wrench_topic`: a geometry_msgs/WrenchStamped (a wrist force-torque
        sensor: the force on the tool), or the node's deformable_flsm/ContactWrenches (the entry
        of collider `collider`). The force is turned into `frame_id` from its message's frame,
        which must be on /tf."""
        import rosbag  # Debian's python3-rosbag; only needed for bags

        try:
            bag = rosbag.Bag(path)
        except Exception as e:  # rosbag raises its own exceptions and IOError
            raise RecordingError(f"{path}: not a readable bag ({e})") from None
        with bag:
            topics = bag.get_type_and_topic_info().topics
            if wrench_topic not in topics:
                raise RecordingError(f"{path}: no topic {wrench_topic} (it has {', '.join(sorted(topics))})")
            kind = topics[wrench_topic].msg_type
            if kind not in ("geometry_msgs/WrenchStamped", "deformable_flsm/ContactWrenches"):
                raise RecordingError(f"{path}: {wrench_topic} is {kind}, not geometry_msgs/WrenchStamped "
                                     "or deformable_flsm/ContactWrenches")
            if kind == "deformable_flsm/ContactWrenches" and not collider:
                raise RecordingError(f"{path}: {wrench_topic} holds every collider's wrench: name the tool's "
                                     "collider")
            edges = _tf_edges(bag)
            wrenches = []
            for _, m, _ in bag.read_messages(topics=[wrench_topic]):
                if kind == "geometry_msgs/WrenchStamped":
                    wrenches.append((m.header.stamp.to_sec(), m.header.frame_id.lstrip("/"), m.wrench.force))
                elif collider in m.ids:
                    w = m.wrenches[list(m.ids).index(collider)]
                    wrenches.append((m.header.stamp.to_sec(), w.header.frame_id.lstrip("/"), w.wrench.force))
        if not wrenches:
            raise RecordingError(f"{path}: {wrench_topic} has no messages" +
                                 (f" with collider '{collider}'" if collider else ""))
        times, poses, forces = [], [], []
        for stamp, frame, f in sorted(wrenches, key=lambda w: w[0]):
            if times and stamp <= times[-1]:
                continue  # the same state again (a node republishing at rest)
            pose = _lookup(edges, frame_id, tool_frame, stamp, path)
            turn = pose if frame == tool_frame else (
                np.array([0, 0, 0, 0, 0, 0, 1.0]) if frame == frame_id else _lookup(edges, frame_id, frame, stamp, path))
            if pose is None or turn is None:
                continue  # before the frames are known
            times.append(stamp)
            poses.append(pose)
            forces.append(_rotate(turn[3:], np.array([f.x, f.y, f.z])))
        if not times:
            raise RecordingError(f"{path}: no transform from '{frame_id}' to '{tool_frame}' on /tf "
                                 f"at the times of {wrench_topic}")
        return cls(times, poses, forces, path, step_means=kind == "deformable_flsm/ContactWrenches")


def _read_csv(path):
    """(header, rows) of a CSV file whose lines starting with # are comments; header [] when empty."""
    with open(path) as f:
        rows = [r for r in csv.reader(line for line in f if not line.lstrip().startswith("#")) if r]
    return ([h.strip() for h in rows[0]] if rows else []), rows[1:]


def _numbers(path, rows, columns=None):
    """The rows' first `columns` values (all when None) as an array of floats."""
    try:
        return np.array([[float(v) for v in r[:columns]] for r in rows])
    except ValueError as e:
        raise RecordingError(f"{path}: a value is not a number ({e})") from None


def _quat_mul(a, b):
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return np.array([aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw,
                     aw * bw - ax * bx - ay * by - az * bz])


def _rotate(q, v):
    p = _quat_mul(_quat_mul(q, [v[0], v[1], v[2], 0.0]), [-q[0], -q[1], -q[2], q[3]])
    return p[:3]


def _compose(a, b):
    return np.concatenate([a[:3] + _rotate(a[3:], b[:3]), _quat_mul(a[3:], b[3:])])


def _interpolate(link, stamp):
    """A link's transform at `stamp`: between the two around it (positions linearly, rotations
    normalised linearly), the nearest past the ends; None before its first (/tf_static's,
    stored at 0, hold always)."""
    stamps = [e[0] for e in link]
    k = int(np.searchsorted(stamps, stamp, side="right"))
    if k == 0:
        return (link[0][1], link[0][2]) if stamps[0] <= 0.0 else None
    if k == len(link) or stamps[k] == stamps[k - 1]:
        return link[k - 1][1], link[k - 1][2]
    a, b = link[k - 1][2], link[k][2]
    s = (stamp - stamps[k - 1]) / (stamps[k] - stamps[k - 1])
    qb = b[3:] if np.dot(a[3:], b[3:]) >= 0 else -b[3:]
    q = (1 - s) * a[3:] + s * qb
    return link[k - 1][1], np.concatenate([(1 - s) * a[:3] + s * b[:3], q / np.linalg.norm(q)])


def _tf_edges(bag):
    """The bag's /tf and /tf_static as child -> [(stamp, parent, 7-vector)] sorted by stamp
    (/tf_static's at 0: they hold always)."""
    edges = {}
    for topic, msg, _ in bag.read_messages(topics=["/tf", "/tf_static"]):
        for tr in msg.transforms:
            t, r = tr.transform.translation, tr.transform.rotation
            edges.setdefault(tr.child_frame_id.lstrip("/"), []).append(
                (0.0 if topic == "/tf_static" else tr.header.stamp.to_sec(), tr.header.frame_id.lstrip("/"),
                 np.array([t.x, t.y, t.z, r.x, r.y, r.z, r.w])))
    for child in edges:
        edges[child].sort(key=lambda e: e[0])
    return edges


def _rotation_matrix(q):
    x, y, z, w = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def _lookup(edges, root, frame, stamp, path):
    """The pose of `frame` in `root` at `stamp`, composed along the chain of /tf (None when a
    link of it has no transform yet)."""
    pose = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0])
    seen = set()
    while frame != root:
        if frame in seen or frame not in edges:
            raise RecordingError(f"{path}: /tf has no chain from '{root}' to '{frame}'")
        seen.add(frame)
        found = _interpolate(edges[frame], stamp)
        if found is None:
            return None
        parent, t = found
        pose = _compose(t, pose)
        frame = parent
    return pose


class Markers:
    """Points on the object over time: times (M,) s from the recording's start, rest (P, 3) where
    they are at rest (the first time), positions (M, P, 3) (m, simulation frame). Ordered (markers,
    a tracked cloud): point p is the same material point at every time. Unordered (a depth
    camera's cloud, cropped to the object): P points sampled from each cloud, no point the same
    material point at two times; the rest's points are followed as material points, and compared
    with each later cloud along the surface's normals (fit.cloud_residuals)."""

    def __init__(self, times, rest, positions, source="markers", ordered=True):
        self.times = np.asarray(times, dtype=float)
        self.rest = np.asarray(rest, dtype=float)
        self.positions = np.asarray(positions, dtype=float)
        self.source = source
        self.ordered = bool(ordered)
        m, p = len(self.times), len(self.rest)
        if m < 2 or p < 1 or self.positions.shape != (m, p, 3) or self.rest.shape != (p, 3):
            raise RecordingError(f"{source}: markers need two or more times of the same points")
        if not (np.all(np.isfinite(self.positions)) and np.all(np.isfinite(self.times))):
            raise RecordingError(f"{source}: the markers are not all finite")
        if np.any(np.diff(self.times) <= 0.0):
            raise RecordingError(f"{source}: its times must increase")

    @classmethod
    def from_csv(cls, path):
        """Columns time, marker, x, y, z: every marker at every time; the first time is the rest."""
        header, rows = _read_csv(path)
        if header[:5] != ["time", "marker", "x", "y", "z"]:
            raise RecordingError(f"{path}: the header must be time,marker,x,y,z")
        data = _numbers(path, rows, 5)
        if data.ndim != 2 or len(data) == 0:
            raise RecordingError(f"{path}: no markers")
        times = np.unique(data[:, 0])
        ids = np.unique(data[:, 1]).astype(int)
        if len(data) != len(times) * len(ids):
            raise RecordingError(f"{path}: every marker must be given at every time "
                                 f"({len(ids)} markers, {len(times)} times, {len(data)} rows)")
        order = np.lexsort((data[:, 1], data[:, 0]))
        positions = data[order, 2:5].reshape(len(times), len(ids), 3)
        return cls(times, positions[0], positions, path)

    @classmethod
    def cloud_from_csv(cls, path, points=600, box=None, seed=0):
        """An unordered cloud from columns time, x, y, z (any number of points at each time; the
        first time is the rest), cropped to `box` ([x0, y0, z0, x1, y1, z1], m) when given and
        sampled to `points` points per time (see sample_cloud)."""
        header, rows = _read_csv(path)
        if header[:4] != ["time", "x", "y", "z"]:
            raise RecordingError(f"{path}: the header must be time,x,y,z")
        data = _numbers(path, rows, 4)
        if data.ndim != 2 or len(data) == 0:
            raise RecordingError(f"{path}: no points")
        times = np.unique(data[:, 0])
        rng = np.random.default_rng(seed)
        clouds = [sample_cloud(data[data[:, 0] == t, 1:4], points, box, rng, f"{path} at {t} s")
                  for t in times]
        return cls(times, clouds[0], np.stack(clouds), path, ordered=False)

    @classmethod
    def cloud_from_bag(cls, path, topic, frame_id, start, end, interval=0.1, points=600, box=None,
                       seed=0):
        """An unordered cloud from a bag's sensor_msgs/PointCloud2 (a depth camera's points,
        organized or not; NaN points skipped): the last cloud at or before `start` is the rest,
        then one every `interval` s or more up to `end`, each cropped to `box` and sampled to
        `points` points (see sample_cloud); times from `start`."""
        rng = np.random.default_rng(seed)
        rest, times, clouds = _read_clouds(
            path, topic, frame_id, start, end, interval,
            lambda xyz, t: sample_cloud(xyz, points, box, rng, f"{path} {topic} at {t:.3f} s"))
        if rest is None:
            raise RecordingError(f"{path}: {topic} has no cloud at or before the recording's start (the rest)")
        if not clouds:
            raise RecordingError(f"{path}: {topic} has no cloud during the recording")
        return cls(np.concatenate([[0.0], times]), rest, np.stack([rest] + clouds), f"{path} {topic}",
                   ordered=False)

    @classmethod
    def from_bag(cls, path, topic, frame_id, start, end, interval=0.1):
        """Markers from a bag's sensor_msgs/PointCloud2 whose points are the same material points
        in the same order in every message (the node's ~particles): the last cloud at or before
        `start` (the recording's clock) is the rest, then one cloud every `interval` s or more up
        to `end`; times from `start`."""
        rest, times, clouds = _read_clouds(path, topic, frame_id, start, end, interval, lambda xyz, t: xyz)
        if rest is None:
            raise RecordingError(f"{path}: {topic} has no cloud at or before the recording's start (the rest)")
        if not clouds or any(c.shape != rest.shape for c in clouds):
            raise RecordingError(f"{path}: {topic} needs clouds of the same points during the recording")
        return cls(np.concatenate([[0.0], times]), rest, np.stack([rest] + clouds), f"{path} {topic}")


def sample_cloud(xyz, points, box, rng, source):
    """`points` rows of the finite points of xyz (N, 3) inside `box` ([x0, y0, z0, x1, y1, z1] or
    None): drawn without replacement when there are enough, else every one and the rest drawn
    again (a nearest-neighbour distance does not mind a repeated point)."""
    xyz = xyz[np.all(np.isfinite(xyz), axis=1)]
    if box is not None:
        lo, hi = np.asarray(box[:3], dtype=float), np.asarray(box[3:], dtype=float)
        xyz = xyz[np.all((xyz >= lo) & (xyz <= hi), axis=1)]
    if len(xyz) == 0:
        raise RecordingError(f"{source}: no finite point" + (" inside the box" if box is not None else ""))
    if len(xyz) >= points:
        return xyz[rng.choice(len(xyz), points, replace=False)]
    return np.concatenate([xyz, xyz[rng.choice(len(xyz), points - len(xyz), replace=True)]])


def _read_clouds(path, topic, frame_id, start, end, interval, convert):
    """A bag's sensor_msgs/PointCloud2 on `topic`, each in the simulation frame `frame_id` (a cloud
    in another frame, a camera's optical frame, turned into it by the bag's /tf and /tf_static at
    its stamp) as convert(xyz (N, 3), stamp): the last at or before `start` (the rest; None
    without), then one every `interval` s or more up to `end` with its time from `start`. Returns
    (rest, times, clouds)."""
    import rosbag

    with rosbag.Bag(path) as bag:
        topics = bag.get_type_and_topic_info().topics
        if topic not in topics:
            raise RecordingError(f"{path}: no topic {topic} (it has {', '.join(sorted(topics))})")
        if topics[topic].msg_type != "sensor_msgs/PointCloud2":
            raise RecordingError(f"{path}: {topic} is {topics[topic].msg_type}, not sensor_msgs/PointCloud2")
        edges = None
        rest, times, clouds = None, [], []
        for _, m, _ in bag.read_messages(topics=[topic]):
            t = m.header.stamp.to_sec()
            due = t <= start + 1e-9 or (t <= end + 1e-9 and rest is not None and
                                        t - start - (times[-1] if times else 0.0) >= interval - 1e-9)
            if not due:
                continue
            xyz = _cloud_xyz(m, path, topic)
            frame = m.header.frame_id.lstrip("/")
            if frame != frame_id:
                if edges is None:
                    edges = _tf_edges(bag)
                try:
                    pose = _lookup(edges, frame_id, frame, t, path)
                except RecordingError:
                    raise RecordingError(f"{path}: {topic} is in '{frame}', and the bag's /tf has no chain from "
                                         f"the simulation frame '{frame_id}' to it: record /tf (and "
                                         "/tf_static) with the clouds") from None
                if pose is None:
                    continue  # before its frame is known
                xyz = xyz @ _rotation_matrix(pose[3:]).T + pose[:3]
            if t <= start + 1e-9:
                rest = convert(xyz, t)
            else:
                times.append(t - start)
                clouds.append(convert(xyz, t))
    return rest, times, clouds


def _cloud_xyz(msg, path, topic):
    """(N, 3) float64 x, y, z of a PointCloud2 whose x, y, z are float32."""
    fields = {f.name: f for f in msg.fields}
    if not all(n in fields and fields[n].datatype == 7 for n in ("x", "y", "z")):  # 7: FLOAT32
        raise RecordingError(f"{path}: {topic} has no float32 x, y, z")
    n = msg.width * msg.height
    raw = np.frombuffer(msg.data, dtype=np.uint8).reshape(n, msg.point_step)
    out = np.empty((n, 3))
    for k, name in enumerate(("x", "y", "z")):
        o = fields[name].offset
        out[:, k] = raw[:, o:o + 4].copy().view("<f4" if not msg.is_bigendian else ">f4")[:, 0]
    return out
