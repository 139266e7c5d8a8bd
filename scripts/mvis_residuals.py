"""Residual statistics and plots of an mvis result without a truth (scripts/evaluate RESULT_DIR):
what a user with a real recording can check. Python 3 with Debian's numpy and matplotlib.

Inputs (include/mvis/estimator/result_directory.h; the residuals are written by mvis_offline
--batch, an online result has only the calibration over time):
  RESULT_DIR/corner_residuals.csv    every corner: stamp, camera, board point, detected u v,
                                     residual du dv [px] (projected - detected), pixel sigma
  RESULT_DIR/inertial_residuals.csv  every inertial factor: stamp, sensor, size, chi-square
  RESULT_DIR/calibration.csv         the calibration with its standard deviations over time

The corners' correlation over time: the same board corner seen by the same camera in
consecutive frames, its residuals' autocorrelation rho(k) pooled over every corner (per-corner
means kept: a corner that stays off is correlation too), used up to the first lag where it is
not significant (under 3 / sqrt(pairs)), and beyond MAX_LAG frames as at MAX_LAG when still
significant there. What that correlation does to the information: a corner seen in a run of N frames
tells what N / F independent frames would, F = 1 + 2 sum_{k<N} (1 - k/N) rho(k) (the variance
inflation of a correlated run's mean); F is averaged over every run of every corner, weighted by
N. White errors give F = 1. The calibration's sigmas, computed as if the corners were white with
the configured pixel sigma s, are then too small by about sqrt(F) * RMS / s (RMS the corners'
own per-axis RMS): that is the inflation printed.
"""
import csv
import math
import os
from collections import defaultdict

import numpy as np

import mvis_evaluation as ev

MAX_LAG = 200


def read_corner_residuals(path):
    """{camera: {"t" (n, s), "key" (n board-point tuples), "uv" (n, 2), "e" (n, 2)}}."""
    out = defaultdict(lambda: {"t": [], "key": [], "uv": [], "e": [], "sigma": None})
    with open(path) as f:
        for row in csv.DictReader(f):
            c = out[row["camera"]]
            c["sigma"] = float(row["sigma"])
            c["t"].append(ev.parse_stamp(row["stamp"]) * 1e-9)
            c["key"].append((row["x"], row["y"], row["z"], row["corner"]))
            c["uv"].append((float(row["u"]), float(row["v"])))
            c["e"].append((float(row["du"]), float(row["dv"])))
    for c in out.values():
        c["t"] = np.array(c["t"])
        c["uv"] = np.array(c["uv"]).reshape(-1, 2)
        c["e"] = np.array(c["e"]).reshape(-1, 2)
    return dict(out)


def read_inertial_residuals(path):
    """{sensor: {"t" (n, s), "residuals" (n), "chi2" (n)}}."""
    out = defaultdict(lambda: {"t": [], "residuals": [], "chi2": []})
    with open(path) as f:
        for row in csv.DictReader(f):
            s = out[row["sensor"]]
            s["t"].append(ev.parse_stamp(row["stamp"]) * 1e-9)
            s["residuals"].append(int(row["residuals"]))
            s["chi2"].append(float(row["chi_square"]))
    return {k: {key: np.array(v) for key, v in s.items()} for k, s in out.items()}


def temporal_correlation(c):
    """(rho (lags 0..MAX_LAG), F: the run-length-weighted variance inflation) of one camera's
    corner residuals over its frames."""
    frames = np.unique(c["t"])
    index = {t: i for i, t in enumerate(frames)}
    tracks = defaultdict(dict)  # corner -> {frame index: residual}
    for t, key, e in zip(c["t"], c["key"], c["e"]):
        if key[0] == "nan":  # without a board corners have no identity across tags here
            continue
        tracks[key][index[t]] = e
    num = np.zeros(MAX_LAG + 1)
    den = np.zeros(MAX_LAG + 1)
    pairs_at = np.zeros(MAX_LAG + 1)
    runs = []  # lengths of runs of consecutive frames
    for track in tracks.values():
        f = np.array(sorted(track))
        e = np.array([track[i] for i in f])
        position = {fi: k for k, fi in enumerate(f)}
        breaks = np.flatnonzero(np.diff(f) != 1)
        runs += list(np.diff(np.concatenate([[0], breaks + 1, [len(f)]])))
        for k in range(MAX_LAG + 1):
            pairs = [(position[fi], position[fi + k]) for fi in f if fi + k in position]
            if not pairs:
                continue
            a = np.array(pairs)
            num[k] += np.sum(e[a[:, 0]] * e[a[:, 1]])
            den[k] += 0.5 * (np.sum(e[a[:, 0]] ** 2) + np.sum(e[a[:, 1]] ** 2))
            pairs_at[k] += 2 * len(a)  # both axes
    rho = np.where(den > 0, num / np.maximum(den, 1e-300), 0.0)
    # Lags up to the first whose correlation is not significant (3 / sqrt(pairs): white
    # errors' estimates scatter that much); beyond MAX_LAG as at MAX_LAG only if significant
    # there. Without the cut, the noise of a few hundred estimates would add up.
    significant = rho > 3.0 / np.sqrt(np.maximum(pairs_at, 1.0))
    cut = int(np.argmin(significant[1:])) + 1 if not np.all(significant[1:]) else MAX_LAG + 1
    rho_used = np.where(np.arange(MAX_LAG + 1) < cut, rho, 0.0)
    total = weighted = 0.0
    for n in runs:
        k = np.arange(1, n)
        r = rho_used[np.minimum(k, MAX_LAG)]
        weighted += n * (1.0 + 2.0 * np.sum((1.0 - k / n) * r))
        total += n
    return rho, (weighted / total if total > 0 else math.nan), (float(np.median(runs))
                                                                  if runs else math.nan)


def within_frame_correlation(c):
    """Mean correlation of two corners' residuals in the same frame (per axis, pooled)."""
    sums = defaultdict(lambda: np.zeros(2))
    squares = defaultdict(lambda: np.zeros(2))
    counts = defaultdict(int)
    for t, e in zip(c["t"], c["e"]):
        sums[t] += e
        squares[t] += e * e
        counts[t] += 1
    num = den = 0.0
    for t in sums:
        n = counts[t]
        if n < 2:
            continue
        num += float(np.sum(sums[t] ** 2 - squares[t]))
        den += float((n - 1) * np.sum(squares[t]))
    return num / den if den > 0 else math.nan


def analyse(result_dir, out_dir):
    """Plots and a markdown summary of a batch result's residuals; returns the summary text."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    os.makedirs(out_dir, exist_ok=True)
    lines = ["# Residuals of %s" % result_dir, ""]
    corners_path = os.path.join(result_dir, "corner_residuals.csv")
    if os.path.exists(corners_path):
        corners = read_corner_residuals(corners_path)
        sigma = next(iter(corners.values()))["sigma"]
        lines += ["Corner residuals (per-axis RMS; the batch weighed them with %.3g px):" % sigma,
                  "",
                  "| camera | corners | RMS [px] | median abs [px] | largest [px] | "
                  "within-frame correlation | median run [frames] | variance inflation F | "
                  "sigma inflation sqrt(F) RMS / sigma |",
                  "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
        inflation = {}
        for name in sorted(corners):
            c = corners[name]
            norm = np.linalg.norm(c["e"], axis=1)
            rho, F, run = temporal_correlation(c)
            within = within_frame_correlation(c)
            rms = math.sqrt(np.mean(norm ** 2) / 2)
            inflation[name] = math.sqrt(F) * rms / sigma
            lines.append("| %s | %d | %.3f | %.3f | %.2f | %.3f | %.0f | %.1f | %.2f |" % (
                name, len(norm), rms, np.median(np.abs(c["e"])), norm.max(), within, run, F,
                inflation[name]))
            fig, axes = plt.subplots(1, 3, figsize=(16, 5))
            lim = max(4.0 * math.sqrt(np.mean(norm ** 2) / 2), 1e-3)
            axes[0].scatter(c["e"][:, 0], c["e"][:, 1], s=1, alpha=0.2)
            axes[0].set_xlim(-lim, lim)
            axes[0].set_ylim(-lim, lim)
            axes[0].set_aspect("equal")
            axes[0].set_xlabel("du [px]")
            axes[0].set_ylabel("dv [px]")
            axes[0].set_title("%s reprojection errors" % name)
            sc = axes[1].scatter(c["uv"][:, 0], c["uv"][:, 1], c=np.minimum(norm, lim), s=1,
                                 cmap="viridis")
            axes[1].invert_yaxis()
            axes[1].set_aspect("equal")
            axes[1].set_title("over the image (|error| [px], clipped at %.2f)" % lim)
            fig.colorbar(sc, ax=axes[1])
            axes[2].plot(np.arange(len(rho)), rho)
            axes[2].axhline(0.0, color="grey", linestyle=":")
            axes[2].set_xlabel("lag [frames]")
            axes[2].set_ylabel("autocorrelation")
            axes[2].set_title("same corner, consecutive frames: F %.1f" % F)
            fig.tight_layout()
            fig.savefig(os.path.join(out_dir, "%s_residuals.png" % name), dpi=80)
            plt.close(fig)
        lines.append("")
        with open(os.path.join(out_dir, "inflation.csv"), "w") as f:
            f.write("camera,sigma_inflation\n")
            for name in sorted(inflation):
                f.write("%s,%.6g\n" % (name, inflation[name]))
    inertial_path = os.path.join(result_dir, "inertial_residuals.csv")
    if os.path.exists(inertial_path):
        inertial = read_inertial_residuals(inertial_path)
        lines += ["| inertial sensor | factors | chi-square per residual |", "| --- | ---: | ---: |"]
        fig, ax = plt.subplots(figsize=(10, 4))
        t0 = min(s["t"][0] for s in inertial.values())
        for name in sorted(inertial):
            s = inertial[name]
            lines.append("| %s | %d | %.3f |" % (name, len(s["t"]),
                                                  s["chi2"].sum() / s["residuals"].sum()))
            ax.plot(s["t"] - t0, s["chi2"] / s["residuals"], ".", markersize=2, label=name)
        ax.set_xlabel("time [s]")
        ax.set_ylabel("chi-square per residual")
        ax.set_yscale("log")
        ax.legend()
        ax.set_title("inertial factors' whitened residuals (each state's velocity and biases "
                     "are fitted to them: below 1 by construction)")
        fig.tight_layout()
        fig.savefig(os.path.join(out_dir, "inertial_residuals.png"), dpi=80)
        plt.close(fig)
        lines.append("")
    history_path = os.path.join(result_dir, "calibration.csv")
    if os.path.exists(history_path):
        history = ev.read_calibration_csv(history_path)
        # Over time (an online result; a batch has one row): the estimate minus the final one,
        # with its +-3 sigma.
        final = {}
        for name, h in history.items():
            v = h["value"][-1]
            intrinsics = np.concatenate([v[7:15], np.full(24, math.nan)])
            final[name] = (ev.exp_so3(v[0:3]), v[3:6], v[6], intrinsics)
        for name, e in ev.calibration_errors(history, final).items():
            if len(e["t"]) > 1 and not np.all(np.isnan(e["error"][:, 0:7])):
                e["error"] = -e["error"]  # estimate - final
                ev.plot_errors([e], os.path.join(out_dir, name + "_over_time.png"),
                               "%s (%s): estimate minus the final estimate" % (name, e["kind"]))
        lines += ["| sensor | quantity | value | sigma |", "| --- | --- | --- | --- |"]
        for name in sorted(history):
            h = history[name]
            v, sd = h["value"][-1], h["std"][-1]
            for quantity, s, scale, unit in ev.QUANTITIES:
                if np.all(np.isnan(v[s])):
                    continue
                lines.append("| %s | %s [%s] | %s | %s |" % (
                    name, quantity, unit, " ".join("%.4f" % (x * scale) for x in v[s]),
                    " ".join("%.4f" % (x * scale) for x in sd[s])))
        lines.append("")
    text = "\n".join(lines)
    with open(os.path.join(out_dir, "residuals.md"), "w") as f:
        f.write(text)
    return text
