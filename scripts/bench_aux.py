#!/usr/bin/python3
"""Auxiliary-sensor benchmarks for scripts/bench (not tests).

1. Cost per update with 0, 1, 2, 4 and 8 auxiliary IMUs: the simulated VI-Rig's cameras and base
   IMU plus N copies of its auxiliary IMU at different poses (no gyroscope), DURATION s of
   hand-held motion, mvis_offline on one core; the estimator's time per aux IMU and per IMU
   added since the previous N.
2. Consistency of the auxiliary IMU's translation on yaw-only motion (report Sec. 6.3, Fig. 4):
   the VI-Rig on yaw-only motion for several seeds, both aux-velocity models, with the
   degeneracy check off (the models themselves) and on (the default); the mean NEES of
   imu1's translation (3 degrees of freedom, per-axis standard deviations) and its largest
   error/sigma.
3. Without a board, cost against the number of tags in view: boards of 3x3, 6x6 and 10x10 tags
   over the same 0.66 m (the VI-Rig's is 6x6), DURATION s of hand-held motion, mvis_offline
   without the board's file (tag corners as landmarks, the default carried_tags) on one core;
   the estimator's time per tag, and the 6x6 board once more with every tag carried
   (--carried-tags 0) against the default; then the 6x6 and 10x10 boards with the tags beyond
   the carried ones left out (--no-own-tags).

Usage: bench_aux.py BIN_DIR ROOT OUT_DIR DURATION
"""
import copy
import math
import os
import re
import shutil
import subprocess
import sys

import yaml


def run(cmd):
    return subprocess.run(cmd, check=True, capture_output=True, text=True).stdout


def rotz(angle):
    c, s = math.cos(angle), math.sin(angle)
    return [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]


def matmul(a, b):
    return [[sum(a[i][k] * b[k][j] for k in range(3)) for j in range(3)] for i in range(3)]


def make_rig(root, out, n_aux):
    """The VI-Rig with n_aux auxiliary IMUs (copies of imu1 turned about z) and no gyroscope."""
    shutil.copytree(os.path.join(root, "config", "sim_vi_rig"), out)
    with open(os.path.join(out, "kalibr_imu_chain.yaml")) as f:
        chain = yaml.safe_load(f)
    aux = chain["imu1"]
    new = {"imu0": chain["imu0"]}
    for k in range(n_aux):
        entry = copy.deepcopy(aux)
        T = entry["T_i_b"]
        R = matmul(rotz(k * math.pi / 4), [row[:3] for row in T[:3]])
        t = [T[i][3] + 0.03 * math.cos(k) for i in range(3)]
        entry["T_i_b"] = [R[i] + [t[i]] for i in range(3)] + [[0.0, 0.0, 0.0, 1.0]]
        entry["rostopic"] = "/imu%d" % (k + 1)
        new["imu%d" % (k + 1)] = entry
    with open(os.path.join(out, "kalibr_imu_chain.yaml"), "w") as f:
        yaml.safe_dump(new, f, default_flow_style=None, sort_keys=False)


def sim_yaml(root, out_path, duration, motion="handheld", seed=1):
    with open(os.path.join(root, "config", "sim_vi_rig", "sim.yaml")) as f:
        text = f.read()
    text = re.sub(r"(?m)^duration_s:.*$", "duration_s: %s" % duration, text)
    text = re.sub(r"(?m)^motion:.*$", "motion: %s" % motion, text)
    text = re.sub(r"(?m)^seed:.*$", "seed: %d" % seed, text)
    with open(out_path, "w") as f:
        f.write(text)


def offline(bin_dir, data, result, extra=()):
    return run(["taskset", "-c", "0", os.path.join(bin_dir, "mvis_offline"), "--config",
                os.path.join(data, "config"), "--bag", os.path.join(data, "sim.bag"),
                "--output", result, "--truth", os.path.join(data, "truth"),
                "--pixel-sigma", "0.5", *extra])


def scaling(bin_dir, root, out, duration):
    print("== estimator cost with N auxiliary IMUs (VI-Rig cameras + base IMU, %s s, one core)"
          % duration)
    # Most updates only add a state (a solve every third cam0 frame), so the median is the cheap
    # kind; the estimator's total time over the run is what has to grow linearly in N.
    # "per aux IMU": (total - total at N = 0) / N; "each added": (total - the previous N's
    # total) / (N - previous N), the cost of the IMUs added since the line above (the target:
    # flat within 20% from one to eight).
    print("%4s %12s %12s %10s %16s %18s %16s" % ("N", "median [ms]", "p99 [ms]", "real time",
                                              "estimator [s]", "per aux IMU [s]",
                                              "each added [s]"))
    base = None
    previous = None
    for n in [0, 1, 2, 4, 8]:
        rig = os.path.join(out, "rig_%d" % n)
        data = os.path.join(out, "data_%d" % n)
        make_rig(root, rig, n)
        sim = os.path.join(out, "sim_%d.yaml" % n)
        sim_yaml(root, sim, duration)
        run([os.path.join(bin_dir, "mvis_simulate"), "--rig", rig, "--sim", sim, "--output", data,
             "--detections"])
        text = offline(bin_dir, data, os.path.join(out, "result_%d" % n))
        times = re.search(r"median ([\d.]+) ms, p99 ([\d.]+) ms, total ([\d.]+) s", text)
        rt = re.search(r"\(([\d.]+)x real time\)", text)
        total = float(times.group(3))
        base = total if n == 0 else base
        per_aux = "%.3f" % ((total - base) / n) if n > 0 else "-"
        added = "%.3f" % ((total - previous[1]) / (n - previous[0])) if n > 0 else "-"
        previous = (n, total)
        print("%4d %12s %12s %9sx %16.2f %18s %16s" % (n, times.group(1), times.group(2),
                                                       rt.group(1), total, per_aux, added))


def tags(bin_dir, root, out, duration):
    print("== without a board: estimator cost with N tags in view (VI-Rig, %s s, one core)"
          % duration)
    print("%6s %14s %12s %12s %10s %14s %14s %10s" % (
        "tags", "carried", "median [ms]", "p99 [ms]", "real time", "estimator [s]",
        "per tag [s]", "ATE [mm]"))
    span = 0.66  # [m] the VI-Rig board's: 6 tags of 0.088 m with 0.3 of a tag between them
    for n, carried in [(3, None), (6, None), (10, None), (6, "0"), (6, "no own"),
                       (10, "no own")]:
        data = os.path.join(out, "tags_%d" % n)
        if not os.path.isdir(data):
            rig = os.path.join(out, "tags_rig_%d" % n)
            shutil.copytree(os.path.join(root, "config", "sim_vi_rig"), rig)
            grid_path = os.path.join(rig, "aprilgrid.yaml")
            with open(grid_path) as f:
                grid = f.read()
            grid = re.sub(r"(?m)^tagCols:.*$", "tagCols: %d" % n, grid)
            grid = re.sub(r"(?m)^tagRows:.*$", "tagRows: %d" % n, grid)
            grid = re.sub(r"(?m)^tagSize:.*$", "tagSize: %.4f" % (span / (n + 0.3 * (n - 1))),
                          grid)
            with open(grid_path, "w") as f:
                f.write(grid)
            sim = os.path.join(out, "tags_sim_%d.yaml" % n)
            sim_yaml(root, sim, duration)
            run([os.path.join(bin_dir, "mvis_simulate"), "--rig", rig, "--sim", sim, "--output",
                 data, "--detections"])
            os.remove(os.path.join(data, "config", "aprilgrid.yaml"))
        extra = []
        if carried == "0":
            extra = ["--carried-tags", "0"]
        elif carried == "no own":
            extra = ["--no-own-tags"]
        label = (carried or "default").replace(" ", "_")
        text = offline(bin_dir, data, os.path.join(out, "tags_result_%d_%s" % (n, label)), extra)
        times = re.search(r"median ([\d.]+) ms, p99 ([\d.]+) ms, total ([\d.]+) s", text)
        rt = re.search(r"\(([\d.]+)x real time\)", text)
        ate = re.search(r"^ATE.*?: ([\d.]+) mm over", text, re.M)
        total = float(times.group(3))
        print("%6d %14s %12s %12s %9sx %14.2f %14.3f %10s" % (
            n * n, {"0": "every tag", "no own": "12, no own"}.get(carried, "default"),
            times.group(1), times.group(2),
            rt.group(1), total, total / (n * n), ate.group(1) if ate else "-"))


def translation_nees(truth_dir, result_dir, sensor="imu1"):
    with open(os.path.join(truth_dir, "kalibr_imu_chain.yaml")) as f:
        truth = yaml.safe_load(f)[sensor]
    with open(os.path.join(result_dir, "kalibr_imu_chain.yaml")) as f:
        est = yaml.safe_load(f)[sensor]
    ratios = []
    for i in range(3):
        error = truth["T_i_b"][i][3] - est["T_i_b"][i][3]
        ratios.append(error / est["T_i_b_std"]["translation"][i])
    return sum(r * r for r in ratios), max(abs(r) for r in ratios)


def consistency(bin_dir, root, out, duration, seeds):
    print()
    print("== imu1 translation NEES on yaw-only motion (3 dof; consistent: mean ~3), %d seeds, "
          "%s s" % (len(seeds), duration))
    # With the degeneracy check off the models' own consistency shows (report Fig. 4); with it
    # on (the default) the unobservable direction is held at its prior for both.
    runs = {"velocity_state": ["--observability-ratio", "0"],
            "rigid_velocity": ["--observability-ratio", "0"],
            "velocity_state+check": [],
            "rigid_velocity+check": []}
    results = {name: [] for name in runs}
    for seed in seeds:
        data = os.path.join(out, "yaw_%d" % seed)
        sim = os.path.join(out, "yaw_%d.yaml" % seed)
        sim_yaml(root, sim, duration, motion="yaw_only", seed=seed)
        run([os.path.join(bin_dir, "mvis_simulate"), "--rig",
             os.path.join(root, "config", "sim_vi_rig"), "--sim", sim, "--output", data,
             "--detections"])
        for model, extra in runs.items():
            result = os.path.join(out, "yaw_%d_%s" % (seed, model.replace("+", "_")))
            offline(bin_dir, data, result, ["--aux-model", model.split("+")[0]] + extra)
            results[model].append(translation_nees(os.path.join(data, "truth"), result))
    print("%-22s %10s %18s" % ("model", "mean NEES", "max |error|/sigma"))
    for model, values in results.items():
        mean = sum(v[0] for v in values) / len(values)
        worst = max(v[1] for v in values)
        print("%-22s %10.1f %18.1f" % (model, mean, worst))


def main():
    bin_dir, root, out, duration = sys.argv[1:5]
    os.makedirs(out, exist_ok=True)
    scaling(bin_dir, root, out, duration)
    consistency(bin_dir, root, out, duration, seeds=[1, 2, 3, 4])
    tags(bin_dir, root, out, duration)


if __name__ == "__main__":
    main()
