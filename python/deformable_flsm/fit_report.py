"""The outputs of a fit (deformable_flsm.fit): the fitted scene, the report and the plot."""
import math
import os

import numpy as np
import yaml

from deformable_flsm.fit_candidate import cloud_reference, scene_with
from deformable_flsm.scene import load_params


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

