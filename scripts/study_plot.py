#!/usr/bin/python3
"""Chart and stability table of the speed/accuracy study (scripts/study).

    /usr/bin/python3 scripts/study_plot.py DIR

reads DIR/accuracy.csv and DIR/stability.csv (written by flsm_study) and writes
DIR/speed_accuracy.png (error against cost, log-log, one curve per method, every point labelled
resolution/sub-steps) and DIR/stability.md (method x stress scenario); with DIR/indentation.csv,
DIR/indentation.png (the punch's force against the FEM oracle's, against cost).
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
    ("fastlsm-implicit", "FastLSM, implicit step (backward Euler)", "tab:orange", "*"),
    ("fastlsm-nu0", "FastLSM, nu = 0", "tab:olive", "o"),
    ("naive-lsm", "naive LSM", "tab:cyan", "s"),
    ("mass-spring", "mass-spring (explicit)", "tab:red", "^"),
    ("bullet", "Bullet soft body (links, pose matching, volume)", "tab:green", "D"),
    ("bullet-fem", "Bullet deformable (implicit FEM, E and nu)", "tab:purple", "P"),
]
# (scenario, CSV column, title, y label, log y)
PANELS = [
    ("cantilever", "profile_vs_fem", "(a) Cantilever at rest against physics (FEM oracle)",
     "RMS of deflection - FEM's, over FEM's tip deflection", True),
    ("cantilever", "tip_ratio", "(b) Cantilever tip deflection over FEM's (1 = physics)",
     "tip deflection / FEM tip deflection", False),
    ("column", "profile_vs_fem", "(c) Column under its weight at rest against physics (FEM oracle)",
     "RMS of shortening - FEM's, over FEM's top shortening", True),
    ("ear-drag", "error_ref", "(d) Bunny ear drag, whole trajectory: against the method's own\n"
     "converged run (no physical reference: shows convergence, not physics)",
     "RMS vertex distance to own reference / object size", True),
]
STRESS = [("drag-5x", "drag 5x size, release"), ("plane", "collapsed onto a plane"),
          ("scrambled", "scrambled start")]
CPU = "Intel(R) Xeon(R) Processor, 2 cores"
# the machine docs/study/indentation.csv was measured on
INDENTATION_CPU = "AMD EPYC, 2 cores"


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


def value(row, column):
    if column == "tip_ratio":
        return 1.0 + number(row["tip_vs_fem"])
    return number(row[column])


def series(ax, pts, label, color, marker, logy):
    """One method's points (cost, error, label text) on `ax`, its best error for the cost joined
    when the error axis is logarithmic."""
    if not pts:
        return
    ax.scatter([p[0] for p in pts], [p[1] for p in pts], color=color, marker=marker, s=30,
               label=label, zorder=3)
    if logy:
        front = pareto(pts)
        ax.plot([p[0] for p in front], [p[1] for p in front], color=color, lw=1.3, zorder=2)
    for cost, err, text in pts:
        ax.annotate(text, (cost, err), textcoords="offset points", xytext=(4, 3), fontsize=6.5,
                    color=color)


def chart(rows, calibration, path):
    fig, axes = plt.subplots(2, 2, figsize=(16, 12))
    for ax, (scenario, column, title, ylabel, logy) in zip(axes.flat, PANELS):
        for key, label, color, marker in METHODS:
            pts = []
            for r in rows:
                if r["scenario"] != scenario or r["method"] != key or r["reference"] == "1":
                    continue
                cost, err = number(r["cpu_s_per_sim_s"]), value(r, column)
                if r["blew_up"] == "1" or not math.isfinite(err) or (logy and not err > 0):
                    continue
                pts.append((cost, err, "%s/%s" % (r["resolution"], r["substeps"])))
            series(ax, pts, label, color, marker, logy)
        if column == "tip_ratio":
            fem = number(calibration.get("fem_tip", "nan"))
            ax.axhline(1.0, color="black", lw=1.0, label="FEM oracle (physics)")
            for key, text, style in (("timoshenko_tip", "Timoshenko", "--"),
                                     ("euler_bernoulli_tip", "Euler-Bernoulli", ":")):
                v = number(calibration.get(key, "nan"))
                if math.isfinite(v) and fem > 0:
                    ax.axhline(v / fem, color="gray", lw=1.0, ls=style, label=text)
        ax.set_xscale("log")
        if logy:
            ax.set_yscale("log")
        ax.set_xlabel("cost: CPU time per simulated second (s), one thread")
        ax.set_ylabel(ylabel)
        ax.set_title(title, fontsize=9.5)
        ax.grid(True, which="both", lw=0.3, alpha=0.5)
        ax.legend(fontsize=7.5, loc="best")
    fig.suptitle("Speed against accuracy on %s (labels: resolution / sub-steps per 1/60 s frame; "
                 "lines: best error for the cost)" % CPU, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def indentation(rows, path):
    """The punch: force over the FEM oracle's (and its error) against cost, one series per method."""
    fig, axes = plt.subplots(1, 2, figsize=(16, 6.5))
    for ax, logy in zip(axes, (True, False)):
        for key, label, color, marker in METHODS:
            pts = []
            for r in rows:
                ratio = number(r["force_vs_fem"])
                if r["method"] != key or r["blew_up"] == "1" or not math.isfinite(ratio):
                    continue
                err = abs(ratio - 1.0) if logy else ratio
                pts.append((number(r["cpu_s_per_sim_s"]), err,
                            "%s/%s" % (r["resolution"], r["substeps"])))
            series(ax, pts, label, color, marker, logy)
        ax.set_xscale("log")
        if logy:
            ax.set_yscale("log")
            ax.set_ylabel("|punch force / FEM oracle's - 1|")
            ax.set_title("(e) Bonded flat punch, 2 % of the side deep: force error against cost",
                         fontsize=9.5)
        else:
            ax.axhline(1.0, color="black", lw=1.0, label="FEM oracle (physics)")
            ax.set_ylabel("punch force / FEM oracle's")
            ax.set_title("(f) The same runs: force over the oracle's (1 = physics)", fontsize=9.5)
        ax.set_xlabel("cost: CPU time per simulated second (s), one thread")
        ax.grid(True, which="both", lw=0.3, alpha=0.5)
        ax.legend(fontsize=7.5, loc="best")
    fig.suptitle("Under a finger, on %s: a 5 cm cube (E 20 kPa, nu 0.3) held by its base, a punch "
                 "38 %% of its side (labels: cells per side / sub-steps per 1/60 s frame)"
                 % INDENTATION_CPU, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def modulus(pa):
    """Young's modulus in Pa as a person writes it: 5 kPa, 1 MPa."""
    for unit, scale in (("MPa", 1e6), ("kPa", 1e3)):
        if pa >= scale:
            return "%g %s" % (pa / scale, unit)
    return "%g Pa" % pa


def stability(rows, path):
    by = {(r["method"], r["substeps"], r["youngs_modulus_Pa"], r["scenario"]): r for r in rows}
    lines = ["| method | E | sub-steps | " + " | ".join(t for _, t in STRESS) + " |",
             "|---" * (len(STRESS) + 3) + "|"]
    variants = []
    for key, label, _, _ in METHODS:
        settings = sorted({(number(e), int(s), e, s) for m, s, e, _ in by if m == key})
        variants += [(key, label, s, e) for _, _, e, s in settings]
    for key, label, subs, pa in variants:
        cells = []
        for scenario, _ in STRESS:
            r = by.get((key, subs, pa, scenario))
            if r is None:
                cells.append("not run")
                continue
            energy = number(r["peak_kinetic_energy_J"])
            if r["outcome"] == "blew up":
                cells.append("**blew up** at %.3g s (peak energy %.3g J, that frame included)" %
                             (number(r["blow_up_time_s"]), energy))
            else:
                volume = 100 * number(r["volume_change_final"])
                outcome = r["outcome"]
                if outcome == "recovered":
                    outcome = "recovered after %.1f s" % number(r["recovered_after_s"])
                cells.append("%s: error %.2g%% of size, volume %s%%, peak energy %.3g J" %
                             (outcome, 100 * number(r["shape_error"]),
                              ("%+.0f" if abs(volume) >= 10 else "%+.2g") % volume, energy))
        lines.append("| %s | %s | %s | %s |" % (label, modulus(number(pa)), subs, " | ".join(cells)))
    first = rows[0] if rows else {}
    lines.append("")
    lines.append("Bunny at resolution %s (%s particles), frames of %s s, weightless, on %s; "
                 "error = RMS distance to the best rigid fit of the rest shape / size at the end, "
                 "volume = change of the embedded render mesh's volume at the end; "
                 "recovered = error below 1%% at the end, after N s = from the release on (the end of "
                 "the drag's hold, or the start); peak energy = largest kinetic energy after any frame. "
                 "FastLSM runs with the study's Poisson's ratio 0.3 and, for comparison, without the "
                 "Poisson term (nu = 0); its implicit step (nu = 0.3) also at moduli the explicit step "
                 "cannot take in one such sub-step. "
                 "The explicit mass-spring runs at one sub-step and at the fewest sub-steps its linear "
                 "stability bound allows; the legacy Bullet soft body with pose matching (kMT 0.05 per "
                 "1/60 s) and volume conservation (kVC = 0.005 bulk modulus / rest volume, the full "
                 "modulus being unstable). Bullet's deformable body is not in this table: on the bunny "
                 "it costs ~10 s per simulated second at resolution 12." % (
                     first.get("resolution", "?"), first.get("particles", "?"),
                     first.get("frame_step_s", "?"), CPU))
    with open(path, "w") as f:
        f.write("\n".join(lines) + "\n")


def main():
    if len(sys.argv) != 2:
        sys.exit("usage: study_plot.py DIR")
    out = sys.argv[1]
    calibration = {r["quantity"]: r["value"] for r in read(os.path.join(out, "calibration.csv"))}
    chart(read(os.path.join(out, "accuracy.csv")), calibration, os.path.join(out, "speed_accuracy.png"))
    stability(read(os.path.join(out, "stability.csv")), os.path.join(out, "stability.md"))
    print("wrote %s/speed_accuracy.png and %s/stability.md" % (out, out))
    punch = os.path.join(out, "indentation.csv")
    if os.path.exists(punch):
        indentation(read(punch), os.path.join(out, "indentation.png"))
        print("wrote %s/indentation.png" % out)


if __name__ == "__main__":
    main()
