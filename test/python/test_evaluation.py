"""scripts/mvis_evaluation.py and scripts/monte_carlo on small synthetic inputs with known
answers."""
import importlib.machinery
import importlib.util
import math
import os
import sys
import tempfile
import unittest

import numpy as np

SCRIPTS = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "scripts")
sys.path.insert(0, SCRIPTS)
import mvis_evaluation as ev  # noqa: E402


def load_script(name):
    loader = importlib.machinery.SourceFileLoader(name, os.path.join(SCRIPTS, name))
    spec = importlib.util.spec_from_loader(name, loader)
    module = importlib.util.module_from_spec(spec)
    loader.exec_module(module)
    return module


def rot_to_quat(R):
    """x y z w of a rotation matrix (for writing TUM lines)."""
    w = math.sqrt(max(0.0, 1.0 + np.trace(R))) / 2.0
    return [(R[2, 1] - R[1, 2]) / (4 * w), (R[0, 2] - R[2, 0]) / (4 * w),
            (R[1, 0] - R[0, 1]) / (4 * w), w]


def write_tum(path, stamps_ns, positions, rotations):
    with open(path, "w") as f:
        f.write("# timestamp tx ty tz qx qy qz qw\n")
        for t, p, R in zip(stamps_ns, positions, rotations):
            f.write("%d.%09d %.9f %.9f %.9f %.12f %.12f %.12f %.12f\n"
                    % (t // 10**9, t % 10**9, *p, *rot_to_quat(R)))


class Rotations(unittest.TestCase):
    def test_exp_log_round_trip_and_error_convention(self):
        for phi in ([0.1, -0.2, 0.3], [1e-9, 0, 0], [0, 3.1, 0.0], [2.0, -1.0, 0.5]):
            np.testing.assert_allclose(ev.log_so3(ev.exp_so3(phi)), phi, atol=1e-6)
        # R_true = R_est Exp(delta).
        R_est = ev.exp_so3([0.3, 0.2, -0.1])
        delta = np.array([0.01, -0.02, 0.005])
        np.testing.assert_allclose(ev.rotation_error(R_est @ ev.exp_so3(delta), R_est), delta,
                                   atol=1e-12)

    def test_quaternion_matches_exp(self):
        R = ev.exp_so3([0.4, -0.3, 1.2])
        np.testing.assert_allclose(ev.quat_to_rot(*rot_to_quat(R)), R, atol=1e-12)

    def test_stamps_are_exact_nanoseconds(self):
        self.assertEqual(ev.parse_stamp("1700000000.000000001"), 1700000000000000001)
        self.assertEqual(ev.parse_stamp("12.5"), 12500000000)
        self.assertEqual(ev.parse_stamp("-0.25"), -250000000)


class TimeOffsetFloor(unittest.TestCase):
    def test_yaw_oscillation_closed_form(self):
        # Yaw about gravity at a fixed point, psi = A sin(2 pi f t): the specific force never
        # changes, so the floor is the gyroscope's, q / sqrt(T A^2 (2 pi f)^4 / 2) over whole
        # periods (as test_evaluation.cpp checks the C++ twin).
        A, f, T, rate = 0.5, 1.5, 10.0, 500.0
        n = int(T * rate) + 1
        t = 10**18 + np.arange(n, dtype=np.int64) * 2000000
        s = np.arange(n) / rate
        R = np.array([ev.exp_so3([0.0, 0.0, A * math.sin(2 * math.pi * f * x)]) for x in s])
        p = np.tile([0.3, -0.2, 1.2], (n, 1))
        q = 1.7e-4
        expected = q / math.sqrt(T * A * A * (2 * math.pi * f) ** 4 / 2)
        floor = ev.time_offset_floor((t, p, R), q, 2e-3)
        self.assertAlmostEqual(floor / expected, 1.0, delta=2e-3)
        self.assertAlmostEqual(ev.time_offset_floor((t, p, R), q / 2, 2e-3) / floor, 0.5,
                               delta=1e-6)


class Trajectory(unittest.TestCase):
    def setUp(self):
        n = 201  # 10 s at 20 Hz
        self.t = np.arange(n, dtype=np.int64) * 50000000 + 10**18
        s = np.arange(n) * 0.05
        self.p_true = np.stack([np.cos(s), np.sin(0.7 * s), 0.3 * s], axis=1)
        self.R_true = np.array([ev.exp_so3([0.2 * np.sin(x), 0.1 * x, 0.3]) for x in s])

    def test_ate_of_a_rigid_offset(self):
        # The estimate is the truth moved rigidly: ATE in the board frame sees the offset,
        # SE(3)-aligned ATE is zero, RPE is zero.
        R_off, t_off = ev.exp_so3([0.0, 0.0, 0.05]), np.array([0.1, -0.2, 0.05])
        p_est = self.p_true @ R_off.T + t_off
        R_est = np.array([R_off @ R for R in self.R_true])
        pos, ori = ev.ate(p_est, R_est, self.p_true, self.R_true, aligned=True)
        self.assertLess(pos, 1e-9)
        self.assertLess(ori, 1e-9)
        pos, ori = ev.ate(p_est, R_est, self.p_true, self.R_true, aligned=False)
        self.assertGreater(pos, 0.1)
        self.assertAlmostEqual(ori, 0.05, places=9)
        trans, rot = ev.rpe(self.t, p_est, R_est, self.p_true, self.R_true, 1.0)
        self.assertLess(trans, 1e-9)
        self.assertLess(rot, 1e-9)

    def test_ate_of_a_constant_position_error(self):
        p_est = self.p_true + np.array([0.003, 0.0, -0.004])  # 5 mm everywhere
        pos, _ = ev.ate(p_est, self.R_true, self.p_true, self.R_true, aligned=False)
        self.assertAlmostEqual(pos, 0.005, places=12)

    def test_rpe_of_a_drift(self):
        # Position drifting 2 mm/s along world x with identity orientation: over 1 s the
        # relative translation is off by 2 mm.
        R = np.array([np.eye(3)] * len(self.t))
        drift = np.outer((self.t - self.t[0]) * 1e-9, [0.002, 0.0, 0.0])
        trans, rot = ev.rpe(self.t, self.p_true + drift, R, self.p_true, R, 1.0)
        self.assertAlmostEqual(trans, 0.002, places=9)
        self.assertLess(rot, 1e-12)

    def test_interpolated_truth(self):
        truth = (self.t, self.p_true, self.R_true)
        mid = self.t[:-1] + 25000000
        mask, p, R = ev.interpolate_truth(truth, np.concatenate([mid, [self.t[-1] + 1]]))
        self.assertEqual(int(mask.sum()), len(mid))  # the stamp after the truth is dropped
        np.testing.assert_allclose(p, 0.5 * (self.p_true[:-1] + self.p_true[1:]), atol=1e-12)
        # Halfway in rotation: the same angle to both neighbours.
        a = np.linalg.norm(ev.rotation_error(R[10], self.R_true[10]))
        b = np.linalg.norm(ev.rotation_error(self.R_true[11], R[10]))
        self.assertAlmostEqual(a, b, places=9)

    def test_nees_of_one_sigma_errors_is_three(self):
        sigma_r, sigma_p = 0.01, 0.002
        C = np.diag([sigma_r**2] * 3 + [sigma_p**2] * 3)
        R_est = self.R_true[:5]
        R_true = np.array([R @ ev.exp_so3([sigma_r, -sigma_r, sigma_r]) for R in R_est])
        p_est = self.p_true[:5]
        p_true = p_est + np.array([sigma_p, sigma_p, -sigma_p])
        nees_R, nees_p = ev.pose_nees(p_est, R_est, np.array([C] * 5), p_true, R_true)
        np.testing.assert_allclose(nees_R, 3.0, rtol=1e-6)
        np.testing.assert_allclose(nees_p, 3.0, rtol=1e-12)

    def test_trajectory_metrics_from_files(self):
        with tempfile.TemporaryDirectory() as d:
            os.makedirs(os.path.join(d, "truth"))
            os.makedirs(os.path.join(d, "result"))
            write_tum(os.path.join(d, "truth", "trajectory.tum"), self.t, self.p_true, self.R_true)
            p_est = self.p_true + np.array([0.0, 0.004, 0.0])
            write_tum(os.path.join(d, "result", "trajectory.tum"), self.t[::4], p_est[::4],
                      self.R_true[::4])
            with open(os.path.join(d, "result", "pose_covariance.csv"), "w") as f:
                f.write("stamp,tx,ty,tz,qx,qy,qz,qw" + "".join(
                    ",c%d%d" % (r, c) for r in range(6) for c in range(6)) + "\n")
                C = np.diag([1e-6] * 3 + [4e-6] * 3)  # position sigma 2 mm
                for i in (20, 40):
                    f.write("%d.%09d,%s,%s,%s\n" % (
                        self.t[i] // 10**9, self.t[i] % 10**9, ",".join(map(repr, p_est[i])),
                        ",".join(map(repr, rot_to_quat(self.R_true[i]))),
                        ",".join(map(repr, C.flatten()))))
            m = ev.trajectory_metrics(os.path.join(d, "result"), os.path.join(d, "truth"))
        self.assertEqual(m["states"], 51)
        self.assertAlmostEqual(m["ate_position_m"], 0.004, places=8)
        self.assertAlmostEqual(m["ate_second_half_position_m"], 0.004, places=8)
        self.assertLess(m["ate_aligned_position_m"], 1e-8)
        self.assertLess(m["rpe_1s_translation_m"], 1e-8)
        self.assertEqual(m["nees_samples"], 2)
        self.assertAlmostEqual(m["nees_position"], 4.0, places=6)  # (4 mm / 2 mm)^2
        self.assertLess(m["nees_orientation"], 1e-10)

    def test_estimate_in_its_own_frame_is_aligned_first(self):
        # Without a board the estimate lives in its own frame, defined by its first state: here
        # the truth rotated 90 deg about y and shifted, with errors of +-3 mm along the truth's x
        # alternating from state to state. Mapped through the first state (+3 mm), every other
        # state is 6 mm off: ATE 6 mm sqrt(25/51); the NEES uses the covariance rotated into the
        # board frame (3 mm along the estimate's z, which is the truth's x): (36/9 + 0) / 2 = 2,
        # unrotated it would be 18.
        R_a = ev.exp_so3([0.0, math.pi / 2, 0.0])  # estimate frame -> board frame
        t_a = np.array([0.5, -0.2, 1.0])
        sign = np.array([(-1.0) ** (i // 4) for i in range(len(self.t))])
        p_err = self.p_true + np.outer(sign * 0.003, [1.0, 0.0, 0.0])
        p_est = (p_err - t_a) @ R_a  # R_a^T (p - t_a), row-wise
        R_est = np.array([R_a.T @ R for R in self.R_true])
        with tempfile.TemporaryDirectory() as d:
            os.makedirs(os.path.join(d, "truth"))
            os.makedirs(os.path.join(d, "result"))
            open(os.path.join(d, "truth", "aprilgrid.yaml"), "w").close()
            write_tum(os.path.join(d, "truth", "trajectory.tum"), self.t, self.p_true, self.R_true)
            write_tum(os.path.join(d, "result", "trajectory.tum"), self.t[::4], p_est[::4],
                      R_est[::4])
            with open(os.path.join(d, "result", "pose_covariance.csv"), "w") as f:
                f.write("stamp,tx,ty,tz,qx,qy,qz,qw" + "".join(
                    ",c%d%d" % (r, c) for r in range(6) for c in range(6)) + "\n")
                C = np.diag([1e-6] * 3 + [1e-6, 4e-6, 9e-6])  # 1 / 2 / 3 mm along x / y / z
                for i in (20, 40):
                    f.write("%d.%09d,%s,%s,%s\n" % (
                        self.t[i] // 10**9, self.t[i] % 10**9, ",".join(map(repr, p_est[i])),
                        ",".join(map(repr, rot_to_quat(R_est[i]))),
                        ",".join(map(repr, C.flatten()))))
            self.assertTrue(ev.own_frame(os.path.join(d, "result"), os.path.join(d, "truth")))
            m = ev.trajectory_metrics(os.path.join(d, "result"), os.path.join(d, "truth"))
        self.assertTrue(m["aligned_to_truth"])
        self.assertAlmostEqual(m["ate_position_m"], 0.006 * math.sqrt(25 / 51), places=8)
        self.assertLess(m["ate_orientation_rad"], 1e-8)
        self.assertAlmostEqual(m["nees_position"], 2.0, places=6)
        self.assertLess(m["nees_orientation"], 1e-10)


CSV_HEADER = ("stamp,sensor,kind,rx,ry,rz,px,py,pz,time_offset,std_rx,std_ry,std_rz,std_px,"
              "std_py,std_pz,std_time_offset\n")


def write_truth(d):
    R = ev.exp_so3([1.0, 0.0, 0.0])
    with open(os.path.join(d, "kalibr_imucam_chain.yaml"), "w") as f:
        T = np.eye(4)
        T[:3, :3] = R
        T[:3, 3] = [0.1, 0.0, -0.05]
        f.write("cam0:\n  T_cam_imu: %s\n  timeshift_cam_imu: 0.002\n" % T.tolist())
    with open(os.path.join(d, "kalibr_imu_chain.yaml"), "w") as f:
        f.write("imu0:\n  T_i_b: %s\n  time_offset: 0.0\n" % np.eye(4).tolist())
        f.write("imu1:\n  T_i_b: %s\n  time_offset: 0.0\n" % np.eye(4).tolist())
    return R


class Calibration(unittest.TestCase):
    def test_final_errors_and_three_sigma(self):
        with tempfile.TemporaryDirectory() as d:
            R = write_truth(d)
            # Estimate: rotation off by 0.001 rad about x (right perturbation), translation
            # off by (1, -2, 0) mm, time offset by 0.1 ms; std 0.0005 rad / 1 mm / 0.02 ms.
            phi = ev.log_so3(R @ ev.exp_so3([-0.001, 0.0, 0.0]))
            with open(os.path.join(d, "calibration.csv"), "w") as f:
                f.write(CSV_HEADER)
                f.write("1.0,cam0,camera,%r,%r,%r,0.2,0.3,0.4,0.0,nan,nan,nan,nan,nan,nan,nan\n"
                        % tuple(phi))
                f.write("2.0,cam0,camera,%r,%r,%r,0.099,0.002,-0.05,0.0019,0.0005,0.0005,0.0005,"
                        "0.001,0.001,0.001,0.00002\n" % tuple(phi))
                f.write("2.0,imu1,gyroscope,0,0,0.001,nan,nan,nan,0.0,0,0,0,nan,nan,nan,0\n")
            errors = ev.calibration_errors(ev.read_calibration_csv(os.path.join(d,
                                                                               "calibration.csv")),
                                           ev.read_truth_calibration(d))
        cam = errors["cam0"]
        np.testing.assert_allclose(cam["t"], [0.0, 1.0])
        np.testing.assert_allclose(cam["error"][-1, 0:3], [0.001, 0.0, 0.0], atol=1e-9)
        np.testing.assert_allclose(cam["error"][-1, 3:6], [0.001, -0.002, 0.0], atol=1e-12)
        self.assertAlmostEqual(cam["error"][-1, 6], 0.0001, places=12)
        table = {(r["sensor"], r["quantity"]): r for r in ev.final_calibration_table(errors)}
        rot = table[("cam0", "rotation")]
        self.assertAlmostEqual(rot["error"], math.degrees(0.001), places=6)
        self.assertEqual((rot["inside"], rot["axes"]), (3, 3))  # 0.001 <= 3 * 0.0005
        np.testing.assert_allclose(rot["normalized"], [2.0, 0.0, 0.0], atol=1e-6)
        trans = table[("cam0", "translation")]
        self.assertAlmostEqual(trans["error"], math.sqrt(5.0), places=6)  # mm
        self.assertEqual(trans["inside"], 3)  # 2 mm <= 3 mm
        offset = table[("cam0", "time offset")]
        self.assertAlmostEqual(offset["error"], 0.1, places=6)  # ms
        self.assertEqual(offset["inside"], 0)  # 0.1 ms > 3 * 0.02 ms
        # A gyroscope has no translation row; its quantities held constant (std 0) say so.
        self.assertNotIn(("imu1", "translation"), table)
        self.assertIsNone(table[("imu1", "rotation")]["inside"])

    def test_intrinsics_errors_when_estimated(self):
        with tempfile.TemporaryDirectory() as d:
            R = write_truth(d)
            with open(os.path.join(d, "kalibr_imucam_chain.yaml"), "a") as f:
                f.write("  intrinsics: [400.0, 401.0, 320.0, 240.0]\n"
                        "  distortion_coeffs: [0.01, -0.02, 0.001, 0.0]\n")
            phi = ev.log_so3(R)
            header = CSV_HEADER.strip() + ",fu,fv,pu,pv,k1,k2,k3,k4," + ",".join(
                "std_" + k for k in ev.INTRINSIC_NAMES) + "\n"
            with open(os.path.join(d, "calibration.csv"), "w") as f:
                f.write(header)
                # fu off by 0.3 px (sigma 0.2), pv by -1.0 px (sigma 0.2: outside 3 sigma),
                # k2 by 0.0005 (sigma 0.001).
                f.write("1.0,cam0,camera,%r,%r,%r,0.1,0.0,-0.05,0.002,1e-3,1e-3,1e-3,1e-3,1e-3,"
                        "1e-3,1e-4,399.7,401.0,320.0,241.0,0.01,-0.0205,0.001,0.0,"
                        "0.2,0.2,0.2,0.2,0.001,0.001,0.001,0.001\n" % tuple(phi))
            history = ev.read_calibration_csv(os.path.join(d, "calibration.csv"))
            errors = ev.calibration_errors(history, ev.read_truth_calibration(d))
            self.assertTrue(ev.intrinsics_estimated(errors["cam0"]))
            ev.plot_intrinsics([errors["cam0"]], os.path.join(d, "i.png"), "cam0")
            self.assertTrue(os.path.getsize(os.path.join(d, "i.png")) > 1000)
        table = {r["quantity"]: r for r in ev.final_calibration_table(errors)}
        self.assertAlmostEqual(table["focal lengths"]["error"], 0.3, places=9)
        self.assertAlmostEqual(table["focal lengths"]["three_sigma"], 0.6, places=9)
        self.assertEqual(table["focal lengths"]["inside"], 2)
        self.assertAlmostEqual(table["centre"]["error"], 1.0, places=9)
        self.assertEqual(table["centre"]["inside"], 1)
        self.assertAlmostEqual(table["distortion"]["error"], 0.0005, places=12)
        self.assertEqual((table["distortion"]["inside"], table["distortion"]["axes"]), (4, 4))

    def test_imu_intrinsics_errors_when_estimated(self):
        with tempfile.TemporaryDirectory() as d:
            write_truth(d)
            R_acc = ev.exp_so3([0.0, 0.003, 0.0])
            with open(os.path.join(d, "kalibr_imu_chain.yaml"), "w") as f:
                f.write("imu0:\n  model: rpng\n  Tw: [[1, 0.002, 0], [0, 1, 0], [0, 0, 1]]\n"
                        "  Tg: [[0, 0, 0], [0.0005, 0, 0], [0, 0, 0]]\n  R_IMUtoACC: %s\n"
                        % R_acc.tolist())
            keys = ev.IMU_INTRINSIC_KEYS
            values = dict(zip(keys, [1, 0.0025, 1, 0, 0, 1, 1, 0, 1, 0, 0, 1,
                                     0, 0, 0, 0.0005, 0, 0, 0, 0, 0] +
                              list(ev.log_so3(R_acc @ ev.exp_so3([0.0, 1e-4, 0.0])))))
            stds = dict(zip(keys, [1e-4] * 12 + [2e-5] * 9 + [1e-4] * 3))
            with open(os.path.join(d, "calibration.csv"), "w") as f:
                f.write(CSV_HEADER.strip() + "," + ",".join(keys) + "," +
                        ",".join("std_" + k for k in keys) + "\n")
                # Tw's (0, 1) off by 0.5e-3 (sigma 1e-4: outside 3 sigma), R_IMUtoACC by 1e-4
                # rad about y (sigma 1e-4), the rest exact; no extrinsic (the base IMU).
                f.write("1.0,imu0,imu," + ",".join(["nan"] * 14) + "," +
                        ",".join(repr(float(values[k])) for k in keys) + "," +
                        ",".join(repr(stds[k]) for k in keys) + "\n")
            errors = ev.calibration_errors(ev.read_calibration_csv(os.path.join(d,
                                                                               "calibration.csv")),
                                           ev.read_truth_calibration(d))
            imu0 = errors["imu0"]
            self.assertTrue(ev.intrinsics_estimated(imu0, ev.IMU_INTRINSICS))
            self.assertFalse(ev.intrinsics_estimated(imu0))
            ev.plot_intrinsics([imu0], os.path.join(d, "i.png"), "imu0", ev.IMU_INTRINSICS)
            self.assertTrue(os.path.getsize(os.path.join(d, "i.png")) > 1000)
        table = {r["quantity"]: r for r in ev.final_calibration_table(errors)}
        self.assertNotIn("rotation", table)  # no extrinsic
        self.assertAlmostEqual(table["Tw"]["error"], 0.5, places=9)  # [1e-3]
        self.assertEqual((table["Tw"]["inside"], table["Tw"]["axes"]), (5, 6))
        self.assertAlmostEqual(table["Tg"]["error"], 0.0, places=9)
        self.assertEqual(table["Tg"]["inside"], 9)
        self.assertAlmostEqual(table["R_IMUtoACC"]["error"], math.degrees(1e-4), places=6)
        self.assertEqual(table["R_IMUtoACC"]["inside"], 3)

    def test_plot_is_written(self):
        t = np.linspace(0, 5, 20)
        run = {"kind": "camera", "t": t, "error": np.outer(np.exp(-t), np.ones(7)) * 1e-3,
               "std": np.outer(1.0 / (1 + t), np.ones(7)) * 1e-3}
        with tempfile.TemporaryDirectory() as d:
            path = os.path.join(d, "cam0.png")
            ev.plot_errors([run, run], path, "cam0")
            with open(path, "rb") as f:
                self.assertEqual(f.read(8), b"\x89PNG\r\n\x1a\n")


class MonteCarloSummary(unittest.TestCase):
    def test_mean_max_and_share_inside(self):
        mc = load_script("monte_carlo")
        metrics = {"ate_position_m": 0.003, "ate_second_half_position_m": 0.0015,
                   "ate_aligned_position_m": 0.002,
                   "rpe_1s_translation_m": 0.001, "nees_orientation": 3.0, "nees_position": 2.5}
        runs = [(1, [{"sensor": "cam0", "quantity": "rotation", "unit": "deg", "error": 0.01,
                      "three_sigma": 0.03, "inside": 3, "axes": 3,
                      "normalized": [1.0, -1.0, 1.0]}], metrics),
                (2, [{"sensor": "cam0", "quantity": "rotation", "unit": "deg", "error": 0.03,
                      "three_sigma": 0.05, "inside": 2, "axes": 3,
                      "normalized": [3.0, 1.0, 1.0]}], metrics)]
        text = mc.summarize(runs)
        # RMS of (1, -1, 1, 3, 1, 1) = sqrt(14 / 6) = 1.53
        self.assertIn("| cam0 | rotation [deg] | 0.0200 | 0.0300 | 0.0400 | 5 of 6 | 1.53 |", text)
        self.assertIn("error/sigma over all axes: 1.53", text)
        self.assertIn("5 of 6 (83.3%)", text)
        self.assertIn("| 2 | 3.00 | 1.50 | 2.00 | 1.00 | 3.00 | 2.50 |", text)

    def test_nees_over_runs(self):
        # Runs of 10 poses with mean NEES 2, 3, 4: mean 3, std 1, standard error 1/sqrt(3); a
        # chi-square (3 n) / n with variance 1 has n = 6. The fifths pool the runs' poses 0-1, ...
        runs = [np.full(10, 2.0), np.full(10, 3.0), np.concatenate([np.full(8, 4.0), [2.0, 6.0]])]
        s = ev.nees_over_runs(runs)
        self.assertAlmostEqual(s["mean"], 3.0, places=12)
        self.assertAlmostEqual(s["std"], 1.0, places=12)
        self.assertAlmostEqual(s["standard_error"], 1.0 / math.sqrt(3.0), places=12)
        self.assertAlmostEqual(s["independent_poses"], 6.0, places=12)
        np.testing.assert_allclose(s["parts"], [3.0, 3.0, 3.0, 3.0, 3.0], atol=1e-12)
        self.assertAlmostEqual(ev.nees_over_runs(runs, dof=6)["independent_poses"], 12.0,
                               places=12)
        mc = load_script("monte_carlo")
        metrics = [{"ate_position_m": 0.0, "ate_second_half_position_m": 0.0,
                    "ate_aligned_position_m": 0.0, "rpe_1s_translation_m": 0.0,
                    "nees_orientation": float(np.mean(a)), "nees_position": float(np.mean(a)),
                    "nees_orientation_poses": a, "nees_position_poses": a} for a in runs]
        text = mc.summarize([(i + 1, [], m) for i, m in enumerate(metrics)])
        self.assertIn("| orientation | 3.00 | 0.58 | 1.00 | 6.0 | "
                      "3.00 / 3.00 / 3.00 / 3.00 / 3.00 |", text)


if __name__ == "__main__":
    unittest.main()
