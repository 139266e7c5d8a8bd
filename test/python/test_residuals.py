"""scripts/mvis_residuals.py (scripts/evaluate without a truth) on synthetic corner residuals
with known correlation, and scripts/compare_calibrations' inflation."""
import os
import sys
import tempfile
import unittest

import numpy as np

SCRIPTS = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "scripts")
sys.path.insert(0, SCRIPTS)
import mvis_residuals as res  # noqa: E402


def corners(frames, n_corners, white, offset, seed):
    """One camera's corners in every frame: white noise of `white` px plus, per corner, a
    constant offset of `offset` px (a correlation that never decays)."""
    rng = np.random.default_rng(seed)
    bias = rng.normal(0.0, offset, (n_corners, 2))
    t, key, e = [], [], []
    for f in range(frames):
        for i in range(n_corners):
            t.append(f * 0.05)
            key.append((str(i), "0", "0", "-1"))
            e.append(bias[i] + rng.normal(0.0, white, 2))
    return {"t": np.array(t), "key": key, "uv": np.zeros((len(t), 2)), "e": np.array(e),
            "sigma": 0.5}


class CornerCorrelation(unittest.TestCase):
    def test_white_errors_are_not_inflated(self):
        # 200 frames x 40 corners of white noise: F = 1 (every lag's correlation is noise of
        # about 1/sqrt(16000) and the significance cut stops at the first).
        rho, F, run = res.temporal_correlation(corners(200, 40, 0.5, 0.0, 1))
        self.assertEqual(run, 200)
        self.assertAlmostEqual(rho[0], 1.0)
        self.assertLess(abs(F - 1.0), 0.05)

    def test_a_constant_offset_per_corner_is(self):
        # Offsets of 0.3 px under 0.3 px of white noise: rho(k) = 0.5 at every lag, and a run of
        # N = 100 frames has F = 1 + 2 sum_{k<N} (1 - k/N) 0.5 = 1 + 0.5 (N - 1) = 50.5.
        rho, F, _ = res.temporal_correlation(corners(100, 200, 0.3, 0.3, 2))
        self.assertAlmostEqual(float(np.mean(rho[1:50])), 0.5, delta=0.05)
        self.assertAlmostEqual(F, 50.5, delta=5.0)

    def test_within_frame_correlation(self):
        # A common shift of every corner in a frame (0.2 px) over white 0.2 px: correlation 0.5.
        rng = np.random.default_rng(3)
        t, e = [], []
        for f in range(300):
            shift = rng.normal(0.0, 0.2, 2)
            for _ in range(30):
                t.append(float(f))
                e.append(shift + rng.normal(0.0, 0.2, 2))
        c = {"t": np.array(t), "e": np.array(e)}
        self.assertAlmostEqual(res.within_frame_correlation(c), 0.5, delta=0.05)
        white = {"t": np.array(t), "e": rng.normal(0.0, 0.2, (len(t), 2))}
        self.assertLess(abs(res.within_frame_correlation(white)), 0.02)

    def test_analyse_writes_the_inflation(self):
        # White errors of 0.25 px weighed with 0.5 px: the sigmas are 2x too large, inflation 0.5.
        with tempfile.TemporaryDirectory() as d:
            c = corners(60, 30, 0.25, 0.0, 4)
            with open(os.path.join(d, "corner_residuals.csv"), "w") as f:
                f.write("stamp,camera,x,y,z,corner,u,v,du,dv,sigma\n")
                for t, key, e in zip(c["t"], c["key"], c["e"]):
                    f.write("%.9f,cam0,%s,%s,%s,%s,100,100,%.6f,%.6f,0.5\n" % (t, *key, *e))
            out = os.path.join(d, "evaluation")
            text = res.analyse(d, out)
            self.assertIn("| cam0 | 1800 |", text)
            with open(os.path.join(out, "inflation.csv")) as f:
                rows = f.read().splitlines()
            self.assertEqual(rows[0], "camera,sigma_inflation")
            self.assertAlmostEqual(float(rows[1].split(",")[1]), 0.5, delta=0.03)
            self.assertTrue(os.path.exists(os.path.join(out, "cam0_residuals.png")))

    def test_an_online_result_gets_its_calibration_over_time(self):
        # No residuals (an online result): the calibration's table and its plot over time.
        with tempfile.TemporaryDirectory() as d:
            keys = ["rx", "ry", "rz", "px", "py", "pz", "time_offset"]
            with open(os.path.join(d, "calibration.csv"), "w") as f:
                f.write("stamp,sensor,kind," + ",".join(keys) + "," +
                        ",".join("std_" + k for k in keys) + "\n")
                for k in range(5):
                    value = [0.01 * k, 0.0, 0.0, 0.1, 0.0, 0.0, 0.001]
                    f.write("%d.0,cam0,camera,%s,%s\n" % (
                        100 + k, ",".join(map(str, value)), ",".join(["0.001"] * 7)))
            out = os.path.join(d, "evaluation")
            text = res.analyse(d, out)
            self.assertIn("| cam0 | time offset [ms] | 1.0000 | 1.0000 |", text)
            self.assertTrue(os.path.exists(os.path.join(out, "cam0_over_time.png")))
            self.assertFalse(os.path.exists(os.path.join(out, "inflation.csv")))



def write_calibration(path, value, std):
    """A calibration.csv with one camera row (rotation, translation, time offset)."""
    keys = ["rx", "ry", "rz", "px", "py", "pz", "time_offset"]
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with open(path, "w") as f:
        f.write("stamp,sensor,kind," + ",".join(keys) + "," +
                ",".join("std_" + k for k in keys) + "\n")
        f.write("100.0,cam0,camera,%s,%s\n" % (",".join(map(str, value)),
                                               ",".join(map(str, std))))


class CompareCalibrations(unittest.TestCase):
    def setUp(self):
        import importlib.machinery
        import importlib.util
        loader = importlib.machinery.SourceFileLoader(
            "compare_calibrations", os.path.join(SCRIPTS, "compare_calibrations"))
        spec = importlib.util.spec_from_loader(loader.name, loader)
        self.compare = importlib.util.module_from_spec(spec)
        loader.exec_module(self.compare)

    def test_auto_inflates_the_online_pass_by_its_batch_ratio(self):
        # A batch with the clustered covariance (sigmas 3x the model's for rotations, 1x else)
        # and its online pass: the batch is taken as it is, the online pass's sigmas get the
        # batch's ratio per element; a directory without either keeps its own.
        with tempfile.TemporaryDirectory() as d:
            value = [0.01, 0.0, 0.0, 0.1, 0.0, 0.0, 0.001]
            write_calibration(os.path.join(d, "batch", "calibration.csv"), value,
                              [0.003] * 3 + [0.001] * 4)
            write_calibration(os.path.join(d, "batch", "calibration_model.csv"), value,
                              [0.001] * 7)
            write_calibration(os.path.join(d, "batch", "online", "calibration.csv"), value,
                              [0.001] * 7)
            write_calibration(os.path.join(d, "other", "calibration.csv"), value, [0.001] * 7)
            batch = self.compare.inflation(os.path.join(d, "batch"), None)("cam0")
            online = self.compare.inflation(os.path.join(d, "batch", "online"), None)("cam0")
            other = self.compare.inflation(os.path.join(d, "other"), None)("cam0")
            self.assertEqual(batch, 1.0)
            self.assertEqual(other, 1.0)
            np.testing.assert_allclose(online[0:7], [3.0] * 3 + [1.0] * 4)
            # A rotation 0.012 rad off: 3.79 combined sigmas without the inflation, 2.83 with it.
            shifted = [0.022] + value[1:]
            write_calibration(os.path.join(d, "shifted", "calibration.csv"), shifted,
                              [0.003] * 3 + [0.001] * 4)
            rows = self.compare.compare(self.compare.load(os.path.join(d, "batch", "online")),
                                        self.compare.load(os.path.join(d, "shifted")),
                                        lambda name: online, lambda name: 1.0)
            self.assertAlmostEqual(rows[0][3], 0.012 / np.hypot(0.003, 0.003), places=3)


if __name__ == "__main__":
    unittest.main()
