#!/usr/bin/python3
"""Chart and stability table of the speed/accuracy study (scripts/study).

    /usr/bin/python3 scripts/study_plot.py DIR

reads DIR/accuracy.csv and DIR/stability.csv (written by flsm_study) and writes
DIR/speed_accuracy.png (error against cost, log-log, one curve per method, every point labelled
resolution/sub-steps) and DIR/stability.md (method x stress scenario).
"""
import csv
import math
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

METHODS = [
    ("fastlsm", "FastLSM", "tab:blue", "o"),
    ("naive-lsm", "naive LSM", "tab:cyan", "s"),
    ("mass-spring", "mass-spring (explicit)", "tab:red", "^"),
    ("bullet", "Bullet soft body", "tab:green", "D"),
]
# (scenario, CSV column, title, y label)
PANELS = [
    ("cantilever", "error_ref", "(a) Cantilever at rest: error against the method's reference",
     "RMS vertex distance to the reference / object size"),
    ("ear-drag", "error_ref", "(a) Bunny ear drag, whole trajectory: error against the reference",
     "RMS vertex distance to the reference / object size"),
    ("cantilever", "eb_rms", "(b) Cantilever: deflection profile against Euler-Bernoulli",
     "RMS of y(x)/y(L) - Euler-Bernoulli's"),
]
STRESS = [("drag-5x", "drag 5x size, release"), ("plane", "collapsed onto a plane"),
          ("scrambled", "scrambled start")]


def read(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def number(text):
    try:
        return float(text)
    except ValueError:
        return float("nan")


def pareto(points):
    """Points not beaten in both cost and error by another, sorted by cost."""
    front, best = [], math.inf
    for p in sorted(points, key=lambda q: (q[0], q[1])):
        if p[1] < best:
            front.append(p)
            best = p[1]
    return front


def chart(rows, path):
    fig, axes = plt.subplots(1, len(PANELS), figsize=(19, 6))
    for ax, (scenario, column, title, ylabel) in zip(axes, PANELS):
        for key, label, color, marker in METHODS:
            pts = []
            for r in rows:
                if r["scenario"] != scenario or r["method"] != key or r["reference"] == "1":
                    continue
                cost, err = number(r["wall_s_per_sim_s"]), number(r[column])
                if r["blew_up"] == "1" or not (err > 0 and math.isfinite(err)):
                    continue
                pts.append((cost, err, "%s/%s" % (r["resolution"], r["substeps"])))
            if not pts:
                continue
            ax.scatter([p[0] for p in pts], [p[1] for p in pts], color=color, marker=marker, s=28,
                       label=label, zorder=3)
            front = pareto(pts)
            ax.plot([p[0] for p in front], [p[1] for p in front], color=color, lw=1.3, zorder=2)
            for cost, err, text in pts:
                ax.annotate(text, (cost, err), textcoords="offset points", xytext=(4, 3), fontsize=6.5,
                            color=color)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("cost: wall time per simulated second (s), one thread")
        ax.set_ylabel(ylabel)
        ax.set_title(title, fontsize=9.5)
        ax.grid(True, which="both", lw=0.3, alpha=0.5)
        ax.legend(fontsize=8, loc="best")
    fig.suptitle("Speed against accuracy (labels: resolution / sub-steps per 1/60 s frame; "
                 "lines: best error for the cost)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def stability(rows, path):
    by = {(r["method"], r["scenario"]): r for r in rows}
    lines = ["| method | " + " | ".join(t for _, t in STRESS) + " |",
             "|---" * (len(STRESS) + 1) + "|"]
    for key, label, _, _ in METHODS:
        if not any(m == key for m, _ in by):
            continue
        cells = []
        for scenario, _ in STRESS:
            r = by.get((key, scenario))
            if r is None:
                cells.append("not run")
                continue
            energy = number(r["peak_kinetic_energy_J"])
            if r["outcome"] == "blew up":
                cells.append("**blew up** at %.3g s (peak energy %.3g J, that frame included)" %
                             (number(r["blow_up_time_s"]), energy))
            else:
                volume = 100 * number(r["volume_change_final"])
                cells.append("%s: error %.2g%% of size, volume %s%%, peak energy %.3g J" %
                             (r["outcome"], 100 * number(r["shape_error"]),
                              ("%+.0f" if abs(volume) >= 10 else "%+.2g") % volume, energy))
        lines.append("| %s | %s |" % (label, " | ".join(cells)))
    first = rows[0] if rows else {}
    lines.append("")
    lines.append("Bunny at resolution %s (%s particles), time step %s s in one sub-step, weightless; "
                 "error = RMS distance to the best rigid fit of the rest shape / size at the end, "
                 "volume = change of the embedded render mesh's volume at the end; "
                 "recovered = error below 1%%; peak energy = largest kinetic energy after any frame." % (first.get("resolution", "?"), first.get("particles", "?"),
                                                   first.get("frame_step_s", "?")))
    with open(path, "w") as f:
        f.write("\n".join(lines) + "\n")


def main():
    if len(sys.argv) != 2:
        sys.exit("usage: study_plot.py DIR")
    out = sys.argv[1]
    chart(read(os.path.join(out, "accuracy.csv")), os.path.join(out, "speed_accuracy.png"))
    stability(read(os.path.join(out, "stability.csv")), os.path.join(out, "stability.md"))
    print("wrote %s/speed_accuracy.png and %s/stability.md" % (out, out))


if __name__ == "__main__":
    main()
