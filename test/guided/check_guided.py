#!/usr/bin/python3
"""Guided calibration on the simulated VI-Rig (60 s, tag detections with 0.5 px noise, the
estimator told so; seed 1, started about 2 deg / 2 cm / 10 ms off):

- hand-held motion: the rig declared ready within 40 s, and at that moment every extrinsic and
  time offset within 0.05 deg, 1 mm (cameras), 2 mm (IMUs) and 0.1 ms of the truth;
- yaw-only motion: never ready; the translations the motion cannot tell are in
  calibration_status.csv as unobservable, with the motion that would tell them;
- hand-held with the cameras' intrinsics estimated: the two wide cameras see the board only in
  the image's middle, so their distortion is never converged and the advice names a corner of
  the image; the narrow camera, whose image the board fills, converges.

Usage: check_guided.py MVIS_SIMULATE MVIS_OFFLINE RIG_DIR"""
import csv
import os
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from errors_at_ready import errors_at, ready_stamp  # noqa: E402

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tools"))
from checks import Checks  # noqa: E402

START_S = 1700000000.0  # the simulation's first sample (sim.yaml start_time_s)


def simulate(simulate_bin, rig, out, motion):
    with open(os.path.join(rig, "sim.yaml")) as f:
        text = f.read()
    text = text.replace("motion: handheld", "motion: " + motion)
    sim = out + ".yaml"
    with open(sim, "w") as f:
        f.write(text)
    subprocess.run([simulate_bin, "--rig", rig, "--sim", sim, "--output", out, "--detections"],
                   check=True, capture_output=True)


def run(offline, data, result, *extra):
    subprocess.run([offline, "--config", os.path.join(data, "config"), "--bag",
                    os.path.join(data, "sim.bag"), "--output", result, "--pixel-sigma", "0.5",
                    *extra], check=True, capture_output=True)
    with open(os.path.join(result, "calibration_status.csv")) as f:
        return list(csv.DictReader(f))


def final(rows):
    """Each (sensor, quantity)'s last row."""
    out = {}
    for r in rows:
        out[(r["sensor"], r["quantity"])] = r
    return out


def main(argv):
    simulate_bin, offline, rig = argv[1:4]
    check = Checks()

    with tempfile.TemporaryDirectory() as tmp:
        handheld = os.path.join(tmp, "handheld")
        simulate(simulate_bin, rig, handheld, "handheld")
        result = os.path.join(tmp, "handheld_result")
        run(offline, handheld, result)
        stamp = ready_stamp(result)
        check(stamp is not None, "hand-held: ready")
        if stamp is not None:
            check(stamp - START_S <= 40.0, "hand-held: ready at %.1f s (<= 40)" % (stamp - START_S))
            for sensor, (rot, trans, dt) in errors_at(result, os.path.join(handheld, "truth"),
                                                      stamp).items():
                bound_mm = 1.0 if sensor.startswith("cam") else 2.0
                check(rot <= 0.05 and not trans > bound_mm and dt <= 0.1,
                      "%s at ready: %.4f deg, %.3f mm (<= %.0f), %.4f ms" % (sensor, rot, trans,
                                                                             bound_mm, dt))

        yaw = os.path.join(tmp, "yaw")
        simulate(simulate_bin, rig, yaw, "yaw_only")
        rows = run(offline, yaw, os.path.join(tmp, "yaw_result"))
        check(not any(r["sensor"] == "rig" and r["status"] == "ready" for r in rows),
              "yaw only: never ready")
        unobservable = [r for r in rows if r["status"] == "unobservable"]
        names = sorted({(r["sensor"], r["quantity"]) for r in unobservable})
        print("     unobservable at some point: %s" % names)
        check(("imu1", "translation") in names and ("cam0", "translation") in names,
              "yaw only: imu1's and cam0's translations named unobservable")
        check(bool(unobservable) and all(r["advice"] for r in unobservable),
              "yaw only: each with its advice")

        rows = run(offline, handheld, os.path.join(tmp, "intrinsics_result"),
                   "--estimate-intrinsics")
        last = final(rows)
        for cam in ("cam0", "cam2"):
            r = last.get((cam, "distortion"))
            check(r is not None and r["status"] != "converged" and "corner" in r["advice"],
                  "intrinsics: %s distortion %s (%s)" % (cam, r and r["status"], r and r["advice"]))
        r = last.get(("cam1", "distortion"))
        check(r is not None and r["status"] == "converged",
              "intrinsics: cam1 (its image covered) distortion %s" % (r and r["status"]))
        with open(os.path.join(tmp, "intrinsics_result", "report.md")) as f:
            report = f.read()
        check("cam0's image coverage" in report and "missing: the image's" in report,
              "intrinsics: the report shows cam0's coverage and what is missing")
    return check.status()


if __name__ == "__main__":
    sys.exit(main(sys.argv))
