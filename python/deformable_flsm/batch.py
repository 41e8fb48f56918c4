"""Many scenes run on Dask: a grid or a random set of parameters, each sample's trajectory and
contact wrenches written with an index (a data set for learning).

    ./scripts/flsm batch examples/batch/pokes.yaml [--scheduler tcp://HOST:8786] [--workers N] [--out DIR]
    python3 -m deformable_flsm.batch SPEC.yaml [options]

The spec (paths relative to it):

    scene: [scene.yaml, ...]          # over the package's config/flsm.yaml, as the launch loads them
    seconds: 2.0                      # simulated per sample
    record_every: 3                   # steps between recorded states
    grid:   {youngs_modulus: [1.0e+4, 1.0e+5], damping: [5.0, 20.0]}   # every combination, or
    random: {count: 100, seed: 1, bounds: {youngs_modulus: [1.0e+4, 1.0e+5]}}
    tool:                             # optional: a collider of the scene moved along a path
      id: punch
      path: poke.csv                  # time, x, y, z[, qx, qy, qz, qw] (other columns ignored)

Each sample writes sample_NNNNN.npz (params, times, positions per object, velocities, the wrench
on every collider) and a row of index.csv; samples already written with the same parameters are
skipped, so a stopped batch resumes where it stopped.
"""
import argparse
import csv
import itertools
import json
import math
import os
import sys
import time

import numpy as np
import yaml

from deformable_flsm.fit import Cluster, FitError, _bar, package_config, tool_path
from deformable_flsm.recording import Recording, RecordingError
from deformable_flsm.scene import ParamError, Simulation, load_params


class BatchError(ValueError):
    """A batch that cannot start; the message says what to fix."""


def samples_of(spec):
    """The parameter sets: every combination of `grid`, or `random.count` uniform draws (log-
    uniform where the bounds are positive and a decade or more apart)."""
    if ("grid" in spec) == ("random" in spec):
        raise BatchError("give either grid: {name: [values]} or random: {count, bounds}")
    if "grid" in spec:
        grid = spec["grid"]
        if not isinstance(grid, dict) or not grid or not all(isinstance(v, list) and v for v in grid.values()):
            raise BatchError("grid: a dictionary of parameter names to non-empty lists of values")
        names = list(grid)
        return [dict(zip(names, combo)) for combo in itertools.product(*(grid[n] for n in names))]
    r = spec["random"]
    bounds = r.get("bounds", {}) if isinstance(r, dict) else {}
    count = r.get("count", 0) if isinstance(r, dict) else 0
    if not bounds or not isinstance(count, int) or count < 1:
        raise BatchError("random: needs count >= 1 and bounds: {name: [low, high]}")
    rng = np.random.default_rng(r.get("seed", 1))
    out = []
    for _ in range(count):
        s = {}
        for name, (lo, hi) in bounds.items():
            if not lo < hi:
                raise BatchError(f"random bounds of '{name}': [{lo}, {hi}] must have low < high")
            u = rng.uniform()
            s[name] = float(math.exp(math.log(lo) + u * math.log(hi / lo)) if lo > 0 and hi >= 10 * lo
                            else lo + u * (hi - lo))
        out.append(s)
    return out


def run_sample(index, values, base, seconds, record_every, tool, path, out_dir):
    """Simulates one sample and writes its file; returns its index row."""
    t0 = time.time()
    tree = dict(base)
    tree.update(values)
    name = "sample_%05d.npz" % index
    try:
        sim = Simulation(tree, name)
    except ParamError as e:
        return {"sample": index, "file": "", "status": "refused: %s" % e, "seconds": 0.0, **values}
    steps = int(round(seconds / sim.time_step))
    colliders = sim.colliders
    times, states, vels, wrenches = [], {o: [] for o in sim.objects}, {o: [] for o in sim.objects}, []
    # the tool moved a step at a time towards the path's next pose (Simulation.follow)
    moves = sim.follow(tool, tool_path(path, sim.time_step, steps)[1]) if tool else None
    for k in range(steps):
        if moves is not None:
            next(moves)
        else:
            sim.step()
        if (k + 1) % record_every == 0 or k + 1 == steps:
            times.append(sim.time)
            for o in sim.objects:
                states[o].append(np.array(sim.positions(o), dtype=np.float32))
                vels[o].append(np.array(sim.velocities(o), dtype=np.float32))
            wrenches.append([np.concatenate([w["force"], w["torque"]])
                             for w in (sim.contact_wrench(c) for c in colliders)])
    arrays = {"times": np.array(times), "params": np.array(json.dumps(values)),
              "colliders": np.array(colliders), "wrenches": np.array(wrenches).reshape(len(times), len(colliders), 6)}
    for o in sim.objects:
        arrays["positions/" + o] = np.stack(states[o])
        arrays["velocities/" + o] = np.stack(vels[o])
        arrays["rest/" + o] = np.array(sim.rest_positions(o), dtype=np.float32)
    tmp = os.path.join(out_dir, name + ".tmp.npz")
    np.savez_compressed(tmp, **arrays)
    os.replace(tmp, os.path.join(out_dir, name))
    return {"sample": index, "file": name, "status": "ok", "seconds": round(time.time() - t0, 3), **values}


def batch(spec_path, out_dir, cluster, log=print, **overrides):
    with open(spec_path) as f:
        spec = yaml.safe_load(f)
    if not isinstance(spec, dict):
        raise BatchError(f"{spec_path}: a batch spec is a dictionary (scene, seconds, grid or random)")
    spec.update({k: v for k, v in overrides.items() if v is not None})
    here = os.path.dirname(os.path.abspath(spec_path))
    rel = lambda p: p if os.path.isabs(p) else os.path.join(here, p)  # noqa: E731
    scene = spec.get("scene", [])
    scene = [scene] if isinstance(scene, str) else scene
    base = load_params(package_config(), *[rel(s) for s in scene])
    base.setdefault("threads", 1)
    seconds = float(spec.get("seconds", 1.0))
    every = int(spec.get("record_every", 1))
    if not seconds > 0 or every < 1:
        raise BatchError("seconds must be > 0 and record_every >= 1")
    samples = samples_of(spec)
    tool, path = None, None
    if "tool" in spec:
        t = spec["tool"]
        if not isinstance(t, dict) or "id" not in t or "path" not in t:
            raise BatchError("tool: needs id (a collider of the scene) and path (a CSV of its poses)")
        tool = t["id"]
        path = _path_csv(rel(t["path"]))
    # the scene is checked once before any sample runs (with the first sample's values)
    try:
        first = Simulation({**base, **samples[0]}, "the batch's scene")
    except ParamError as e:
        raise BatchError(f"the scene cannot be built: {e}") from None
    unknown = sorted({n for v in samples for n in v} & set(first.unknown_params))
    if unknown:
        raise BatchError(f"{', '.join(unknown)}: not parameters of the node (misspelt?)")
    if tool and tool not in first.colliders:
        raise BatchError(f"the scene has no collider '{tool}' (it has: {', '.join(first.colliders) or 'none'})")
    del first
    os.makedirs(out_dir, exist_ok=True)
    index_path = os.path.join(out_dir, "index.csv")
    done = {}
    if os.path.isfile(index_path):
        with open(index_path) as f:
            for row in csv.DictReader(f):
                i = int(row["sample"])
                same = i < len(samples) and all(row.get(n) not in (None, "") and float(row[n]) == float(v)
                                                for n, v in samples[i].items())
                if row["status"] == "ok" and same and os.path.isfile(os.path.join(out_dir, row["file"])):
                    done[i] = row
    todo = [i for i in range(len(samples)) if i not in done]
    if done:
        log("batch: %d of %d samples already written: running the other %d" % (len(done), len(samples), len(todo)))
    t0 = time.time()
    futures = cluster.client.map(run_sample, todo, [samples[i] for i in todo], base=base, seconds=seconds,
                                 record_every=every, tool=tool, path=path, out_dir=os.path.abspath(out_dir),
                                 pure=False, retries=3)
    from distributed import as_completed
    rows = dict(done)
    for n, future in enumerate(as_completed(futures), 1):
        row = future.result()
        rows[row["sample"]] = row
        _write_index(index_path, rows, samples)
        log("batch: %d/%d %s sample %d %s (%.2f s)" % (len(rows), len(samples), _bar(len(rows), len(samples)),
                                                      row["sample"], row["status"], row["seconds"]))
    return {"samples": len(samples), "ran": len(todo), "seconds": round(time.time() - t0, 2),
            "refused": sum(1 for r in rows.values() if r["status"] != "ok")}


def _path_csv(path):
    """A tool path: time, x, y, z[, qx, qy, qz, qw] (a recording's force columns are ignored)."""
    try:
        return Recording.from_csv(path, forces=False)
    except (RecordingError, OSError) as e:
        raise BatchError(f"tool path: {e}") from None


def _write_index(path, rows, samples):
    names = sorted({k for s in samples for k in s})
    tmp = path + ".tmp"
    with open(tmp, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=["sample", "file", "status", "seconds", *names])
        w.writeheader()
        for i in sorted(rows):
            w.writerow({k: rows[i].get(k, "") for k in w.fieldnames})
    os.replace(tmp, path)


def main(argv=None):
    parser = argparse.ArgumentParser(prog="flsm batch", description=__doc__.split("\n\n")[0])
    parser.add_argument("spec")
    parser.add_argument("--scheduler", help="a Dask scheduler (tcp://HOST:8786); default: a local cluster")
    parser.add_argument("--workers", type=int, help="local cluster's worker processes (default: the cores)")
    parser.add_argument("--out", default="batch_out")
    args = parser.parse_args(argv)
    try:
        cluster = Cluster(args.scheduler, args.workers)
        try:
            summary = batch(args.spec, args.out, cluster, log=lambda m: print(m, file=sys.stderr, flush=True))
        finally:
            cluster.close()
    except (BatchError, FitError, RecordingError, ParamError, OSError) as e:
        print("flsm batch: %s" % e, file=sys.stderr)
        return 2
    print(yaml.safe_dump(summary, sort_keys=False), end="")
    return 0


if __name__ == "__main__":
    sys.exit(main())
