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
import os
import sys

import yaml

from deformable_flsm.recording import Markers, Recording, RecordingError  # noqa: F401 (also this module's API)
from deformable_flsm.scene import ParamError, Simulation, load_params  # noqa: F401 (also this module's API)
from deformable_flsm.search import Bracket, Cluster, Cma, Space  # noqa: F401 (also this module's API)
# The fit's parts, each in a module of its own, and their names here (this module's API):
# fit_spec (what to fit), fit_candidate (one candidate's simulation, on the workers), fit_search
# (the generations, the refinement, the standard errors), fit_report (the outputs).
from deformable_flsm.fit_candidate import (  # noqa: F401
    CLOUD_COSINE, CLOUD_FLAT, CLOUD_NEIGHBOURS, CloudReference, cloud_reference, cloud_residuals, evaluate,
    marker_errors, marker_rms, marker_scale, nearest, relative_rms, scene_with, simulate, surface_normals,
    tool_path)
from deformable_flsm.fit_report import plot, write_outputs  # noqa: F401
from deformable_flsm.fit_search import (  # noqa: F401
    REFINE_GAIN, REFINE_ITERATIONS, REFINE_LAMBDAS, REFINE_STEP, _as_best, _bar, _check_scene, _generation, _key,
    _save, _start_or_resume, refine, residual_vector, uncertainty)
from deformable_flsm.fit_spec import (  # noqa: F401
    FITTABLE, OBSERVATIONS, FitError, FitSpec, load_markers, load_recording, package_config)


# --- the fit -------------------------------------------------------------------------------------

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
