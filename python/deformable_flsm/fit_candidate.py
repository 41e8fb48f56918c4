"""The simulation of one candidate of a fit (deformable_flsm.fit), which runs on the workers: the
scene with the candidate's values, the tool's recorded path replayed, the force (and the markers
or the cloud) compared with the recording."""
import copy
import math

import numpy as np

from deformable_flsm.scene import ParamError, Simulation


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

