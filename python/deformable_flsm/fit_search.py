"""The steps of a fit (deformable_flsm.fit): its checkpoint, the scene checked before the search,
one generation of the search on the cluster, the Levenberg-Marquardt refinement of its best and
the standard errors at the optimum."""
import hashlib
import json
import math
import os
import pickle
import time

import numpy as np

from deformable_flsm.fit_candidate import evaluate, marker_errors, marker_scale, scene_with
from deformable_flsm.fit_spec import FitError
from deformable_flsm.scene import ParamError, Simulation
from deformable_flsm.search import Bracket, Cma


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

