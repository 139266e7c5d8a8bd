"""Metrics and plots of an mvis result against a simulation's truth (scripts/evaluate,
scripts/monte_carlo). Python 3 with Debian's numpy, matplotlib and yaml.

Inputs (doc/conventions.md, include/mvis/rig/estimate_log.h):
  RESULT_DIR/calibration.csv      every calibrated sensor after every solve, with std
  RESULT_DIR/pose_covariance.csv  newest pose and its 6x6 tangent covariance, now and then
  RESULT_DIR/trajectory.tum       every window state (imu0 in the board frame)
  TRUTH_DIR/kalibr_imu_chain.yaml, kalibr_imucam_chain.yaml, trajectory.tum

Conventions: a rotation's error is the tangent delta with R_true = R_est Exp(delta) (right
perturbation, the frame of the reported standard deviations); a translation's error is
p_true - p_est; a time offset's, t_true - t_est.
"""
import csv
import math
import os

import numpy as np
import yaml

# ---------------------------------------------------------------- SO(3) / SE(3) helpers


def hat(v):
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def exp_so3(phi):
    phi = np.asarray(phi, dtype=float)
    angle = np.linalg.norm(phi)
    if angle < 1e-12:
        return np.eye(3) + hat(phi)
    k = hat(phi / angle)
    return np.eye(3) + math.sin(angle) * k + (1.0 - math.cos(angle)) * k @ k


def log_so3(R):
    cos = max(-1.0, min(1.0, (np.trace(R) - 1.0) / 2.0))
    angle = math.acos(cos)
    w = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    if angle < 1e-7:
        return 0.5 * w
    if math.pi - angle < 1e-6:
        # Near pi: the axis from the symmetric part.
        B = (R + np.eye(3)) / 2.0
        axis = np.sqrt(np.maximum(np.diag(B), 0.0))
        i = int(np.argmax(axis))
        axis[:] = B[i] / axis[i]
        return angle * axis / np.linalg.norm(axis)
    return angle / (2.0 * math.sin(angle)) * w


def quat_to_rot(x, y, z, w):
    """Hamilton quaternion (x y z w) to a rotation matrix."""
    n = math.sqrt(x * x + y * y + z * z + w * w)
    x, y, z, w = x / n, y / n, z / n, w / n
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def rotation_error(R_true, R_est):
    """delta with R_true = R_est Exp(delta) [rad]."""
    return log_so3(R_est.T @ R_true)


# ---------------------------------------------------------------- reading


def parse_stamp(text):
    """'sec.nsec' (or a plain number) to integer nanoseconds, exactly."""
    text = text.strip()
    negative = text.startswith("-")
    if negative:
        text = text[1:]
    if "." in text:
        sec, frac = text.split(".", 1)
        ns = int(sec or "0") * 1000000000 + int((frac + "000000000")[:9])
    else:
        ns = int(text) * 1000000000
    return -ns if negative else ns


def read_tum(path):
    """Stamps [ns] (int64 array), positions (n x 3), rotations (n x 3 x 3)."""
    stamps, positions, rotations = [], [], []
    with open(path) as f:
        for line in f:
            if not line.strip() or line.startswith("#"):
                continue
            fields = line.split()
            stamps.append(parse_stamp(fields[0]))
            v = [float(x) for x in fields[1:8]]
            positions.append(v[0:3])
            rotations.append(quat_to_rot(*v[3:7]))
    return (np.array(stamps, dtype=np.int64), np.array(positions).reshape(-1, 3),
            np.array(rotations).reshape(-1, 3, 3))


UPPER = ("11", "12", "22", "13", "23", "33")  # upper-triangular elements, column-wise
IMU_INTRINSIC_KEYS = (["tw" + e for e in UPPER] + ["ta" + e for e in UPPER] +
                      ["tg%d%d" % (r + 1, c + 1) for r in range(3) for c in range(3)] +
                      ["acc_rx", "acc_ry", "acc_rz"])
CALIBRATION_KEYS = ["rx", "ry", "rz", "px", "py", "pz", "time_offset",
                    "fu", "fv", "pu", "pv", "k1", "k2", "k3", "k4"] + IMU_INTRINSIC_KEYS


def read_calibration_csv(path):
    """{sensor: {"kind", "t" [ns], "value" (n x 39), "std" (n x 39)}} in file order; columns
    CALIBRATION_KEYS: [rx ry rz px py pz time_offset fu fv pu pv k1 k2 k3 k4], then an rpng
    inertial sensor's Tw, Ta (upper triangular), Tg and Log(R_IMUtoACC) (nan where a file has no
    such column or the sensor no such quantity)."""
    out = {}
    with open(path) as f:
        for row in csv.DictReader(f):
            entry = out.setdefault(row["sensor"], {"kind": row["kind"], "t": [], "value": [],
                                                   "std": []})
            entry["t"].append(parse_stamp(row["stamp"]))
            entry["value"].append([float(row.get(k) or "nan") for k in CALIBRATION_KEYS])
            entry["std"].append([float(row.get("std_" + k) or "nan") for k in CALIBRATION_KEYS])
    n = len(CALIBRATION_KEYS)
    for entry in out.values():
        entry["t"] = np.array(entry["t"], dtype=np.int64)
        entry["value"] = np.array(entry["value"]).reshape(-1, n)
        entry["std"] = np.array(entry["std"]).reshape(-1, n)
    return out


def read_pose_covariance_csv(path):
    """Stamps [ns], positions, rotations, covariances (n x 6 x 6, [dtheta; dp])."""
    stamps, positions, rotations, covariances = [], [], [], []
    if not os.path.exists(path):
        return np.zeros(0, dtype=np.int64), np.zeros((0, 3)), np.zeros((0, 3, 3)), np.zeros(
            (0, 6, 6))
    with open(path) as f:
        reader = csv.reader(f)
        next(reader)
        for row in reader:
            stamps.append(parse_stamp(row[0]))
            v = [float(x) for x in row[1:]]
            positions.append(v[0:3])
            rotations.append(quat_to_rot(*v[3:7]))
            covariances.append(np.array(v[7:43]).reshape(6, 6))
    return (np.array(stamps, dtype=np.int64), np.array(positions).reshape(-1, 3),
            np.array(rotations).reshape(-1, 3, 3), np.array(covariances).reshape(-1, 6, 6))


def matrix4(rows):
    T = np.array(rows, dtype=float)
    return T[:3, :3], T[:3, 3]


def read_truth_calibration(truth_dir):
    """{sensor: (R, p, time_offset, intrinsics)}: T_cam_imu of cameras with [fu fv pu pv] and
    distortion_coeffs, T_i_b of IMUs and gyroscopes with their rpng intrinsics (Tw, Ta upper
    triangular, Tg, R_IMUtoACC as a 3x3 matrix in the last three entries' place: see
    calibration_errors); 32 values, nan where the sensor has none."""
    out = {}
    with open(os.path.join(truth_dir, "kalibr_imucam_chain.yaml")) as f:
        for name, cam in (yaml.safe_load(f) or {}).items():
            R, p = matrix4(cam["T_cam_imu"])
            intrinsics = np.array(list(cam.get("intrinsics", [math.nan] * 4)) +
                                  list(cam.get("distortion_coeffs", [math.nan] * 4)), dtype=float)
            intrinsics = np.concatenate([intrinsics, np.full(24, math.nan)])
            out[name] = (R, p, float(cam.get("timeshift_cam_imu", 0.0)), intrinsics)
    path = os.path.join(truth_dir, "kalibr_imu_chain.yaml")
    if os.path.exists(path):
        with open(path) as f:
            for name, imu in (yaml.safe_load(f) or {}).items():
                R, p = matrix4(imu.get("T_i_b", np.eye(4).tolist()))
                intrinsics = np.full(32, math.nan)
                intrinsics[8:32] = imu_intrinsic_values(imu)
                out[name] = (R, p, float(imu.get("time_offset", 0.0)), intrinsics)
    return out


def imu_intrinsic_values(imu):
    """The 24 IMU intrinsics columns of a kalibr_imu_chain.yaml entry (identity when absent)."""
    def mat(key, default):
        return np.array(imu.get(key, default), dtype=float)
    Tw, Ta = mat("Tw", np.eye(3)), mat("Ta", np.eye(3))
    Tg, R = mat("Tg", np.zeros((3, 3))), mat("R_IMUtoACC", np.eye(3))
    upper = [(0, 0), (0, 1), (1, 1), (0, 2), (1, 2), (2, 2)]
    return np.array([Tw[e] for e in upper] + [Ta[e] for e in upper] + list(Tg.reshape(9)) +
                    list(log_so3(R)))


# ---------------------------------------------------------------- calibration errors

QUANTITIES = (("rotation", slice(0, 3), 180.0 / math.pi, "deg"),
              ("translation", slice(3, 6), 1e3, "mm"),
              ("time offset", slice(6, 7), 1e3, "ms"))
INTRINSICS = (("focal lengths", slice(7, 9), 1.0, "px"),
              ("centre", slice(9, 11), 1.0, "px"),
              ("distortion", slice(11, 15), 1.0, "-"),
              ("Tw", slice(15, 21), 1e3, "1e-3"),
              ("Ta", slice(21, 27), 1e3, "1e-3"),
              ("Tg", slice(27, 36), 1e3, "1e-3"),
              ("R_IMUtoACC", slice(36, 39), 180.0 / math.pi, "deg"))
AXES = "xyz"


def calibration_errors(history, truth):
    """Per sensor: {"kind", "t" [s from the first row], "error" (n x 39: rotation [rad],
    translation [m], time offset [s], intrinsics [px] and distortion, IMU intrinsics), "std"
    (n x 39)} for the sensors that have a truth."""
    out = {}
    t0 = min(h["t"][0] for h in history.values())
    for name, h in history.items():
        if name not in truth:
            continue
        R_t, p_t, td_t, intrinsics_t = truth[name]
        err = np.zeros_like(h["value"])
        for i, v in enumerate(h["value"]):
            err[i, 0:3] = rotation_error(R_t, exp_so3(v[0:3]))
            err[i, 3:6] = p_t - v[3:6]
            err[i, 6] = td_t - v[6]
            err[i, 7:36] = intrinsics_t[0:29] - v[7:36]
            # The accelerometer rotation's error in the estimate's tangent, as the extrinsics'.
            if not (np.any(np.isnan(intrinsics_t[29:32])) or np.any(np.isnan(v[36:39]))):
                err[i, 36:39] = rotation_error(exp_so3(intrinsics_t[29:32]), exp_so3(v[36:39]))
            else:
                err[i, 36:39] = math.nan
        out[name] = {"kind": h["kind"], "t": (h["t"] - t0) * 1e-9, "error": err, "std": h["std"]}
    return out


def final_calibration_table(errors):
    """Rows (sensor, quantity, unit, |final error|, 3 sigma (norm of per-axis 3 sigma), per-axis
    inside count, axes, per-axis error/sigma) for rotation [deg], translation [mm], time offset
    [ms]."""
    rows = []
    for name, e in errors.items():
        err, std = e["error"][-1], e["std"][-1]
        for quantity, cols, scale, unit in QUANTITIES + INTRINSICS:
            x, s = err[cols], std[cols]
            if np.all(np.isnan(x)):
                continue  # a gyroscope's translation, an IMU's intrinsics
            if cols.start >= 7 and not np.any(s > 0.0):
                continue  # intrinsics not estimated
            # held by the configuration (one the motion holds keeps its std: counted)
            held = np.all(s == 0.0)
            inside = int(np.sum(np.abs(x) <= 3.0 * s)) if not held else None
            # Extrinsics: the norm over the axes; intrinsics: the largest element.
            size = (np.max(np.abs(x)), np.max(3.0 * s)) if cols.start >= 7 else (
                np.linalg.norm(x), np.linalg.norm(3.0 * s))
            rows.append({"sensor": name, "quantity": quantity, "unit": unit,
                         "error": float(size[0] * scale),
                         "three_sigma": float(size[1] * scale),
                         "inside": inside, "axes": int(x.size),
                         # error / sigma per axis: standard normal when the sigma is honest
                         "normalized": [] if held else [float(v) for v in x / s]})
    return rows


# ---------------------------------------------------------------- trajectory metrics


def interpolate_truth(truth, stamps):
    """Truth poses at `stamps` [ns]: linear in position, geodesic in rotation; stamps outside
    the truth are dropped. Returns (mask, positions, rotations)."""
    t_true, p_true, R_true = truth
    mask = (stamps >= t_true[0]) & (stamps <= t_true[-1])
    positions, rotations = [], []
    for t in stamps[mask]:
        j = int(np.searchsorted(t_true, t))
        if t_true[min(j, len(t_true) - 1)] == t:
            positions.append(p_true[j])
            rotations.append(R_true[j])
            continue
        i = j - 1
        a = (t - t_true[i]) / float(t_true[j] - t_true[i])
        positions.append((1 - a) * p_true[i] + a * p_true[j])
        rotations.append(R_true[i] @ exp_so3(a * log_so3(R_true[i].T @ R_true[j])))
    return mask, np.array(positions).reshape(-1, 3), np.array(rotations).reshape(-1, 3, 3)


def align_se3(p_est, p_true):
    """R, t minimizing sum |p_true - (R p_est + t)|^2 (Horn/Umeyama without scale)."""
    mu_e, mu_t = p_est.mean(axis=0), p_true.mean(axis=0)
    C = (p_true - mu_t).T @ (p_est - mu_e)
    U, _, Vt = np.linalg.svd(C)
    S = np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt))])
    R = U @ S @ Vt
    return R, mu_t - R @ mu_e


def ate(p_est, R_est, p_true, R_true, aligned):
    """RMSE of position [m] and orientation [rad]; aligned: after the best SE(3) alignment of the
    estimate onto the truth, otherwise in the board frame as estimated."""
    if aligned:
        R, t = align_se3(p_est, p_true)
        p_est = p_est @ R.T + t
        R_est = np.array([R @ Re for Re in R_est])
    dp = p_true - p_est
    dth = np.array([np.linalg.norm(rotation_error(Rt, Re)) for Rt, Re in zip(R_true, R_est)])
    return (float(np.sqrt(np.mean(np.sum(dp * dp, axis=1)))),
            float(np.sqrt(np.mean(dth * dth))))


def rpe(t_ns, p_est, R_est, p_true, R_true, delta_s=1.0):
    """Relative pose error over `delta_s`: RMSE of the translation [m] and rotation [rad] of
    (T_true_i^-1 T_true_j)^-1 (T_est_i^-1 T_est_j) for every i and the first j at least delta_s
    later. Independent of any alignment."""
    trans, rots = [], []
    for i in range(len(t_ns)):
        j = int(np.searchsorted(t_ns, t_ns[i] + int(delta_s * 1e9)))
        if j >= len(t_ns):
            break
        dR_t = R_true[i].T @ R_true[j]
        dp_t = R_true[i].T @ (p_true[j] - p_true[i])
        dR_e = R_est[i].T @ R_est[j]
        dp_e = R_est[i].T @ (p_est[j] - p_est[i])
        E_R = dR_t.T @ dR_e
        E_p = dR_t.T @ (dp_e - dp_t)
        trans.append(np.linalg.norm(E_p))
        rots.append(np.linalg.norm(log_so3(E_R)))
    if not trans:
        return float("nan"), float("nan")
    return (float(np.sqrt(np.mean(np.square(trans)))), float(np.sqrt(np.mean(np.square(rots)))))


def pose_nees(p_est, R_est, cov, p_true, R_true):
    """Per pose: orientation NEES (3 dof) and position NEES (3 dof) from the 6x6 tangent
    covariance [dtheta; dp] with R_true = R_est Exp(dtheta), p_true = p_est + dp."""
    nees_R, nees_p = [], []
    for pe, Re, C, pt, Rt in zip(p_est, R_est, cov, p_true, R_true):
        dth = rotation_error(Rt, Re)
        dp = pt - pe
        nees_R.append(float(dth @ np.linalg.solve(C[0:3, 0:3], dth)))
        nees_p.append(float(dp @ np.linalg.solve(C[3:6, 3:6], dp)))
    return np.array(nees_R), np.array(nees_p)


def nees_over_runs(per_run, dof=3, parts=5):
    """What several runs' pose NEES (one array per run, its poses' NEES in time order, `dof`
    degrees of freedom each) can show together. A run's poses share much of their error (without
    a board: what the first states left relative to the tags stays in every later pose), so one
    run's mean NEES is a few independent samples, not as many as it has poses, and scatters widely
    even for an honest covariance. Returns the mean over the runs of their mean NEES, its standard
    error from the runs' own scatter, that scatter's standard deviation, the number of
    independent poses a run counts as if its mean NEES were chi-square distributed (dof n) / n
    (variance 2 dof / n: n = 2 dof / std^2), and the NEES pooled over the runs in `parts` equal
    parts of the run's poses (flat at dof for an honest covariance, whatever the correlation)."""
    means = np.array([np.mean(a) for a in per_run])
    std = float(np.std(means, ddof=1)) if len(means) > 1 else math.nan
    n = min(len(a) for a in per_run)
    bounds = np.linspace(0, n, parts + 1).astype(int)
    pooled = [float(np.mean([np.mean(a[b0:b1]) for a in per_run]))
              for b0, b1 in zip(bounds[:-1], bounds[1:]) if b1 > b0]
    return {"mean": float(np.mean(means)), "standard_error": std / math.sqrt(len(means)),
            "std": std, "independent_poses": 2.0 * dof / std ** 2 if std > 0 else math.inf,
            "parts": pooled}


def time_offset_floor(truth, gyro_noise_density, accel_noise_density, gravity=9.81):
    """A lower bound on a time offset's standard deviation [s] from the base IMU's white noise
    along a trajectory (imu0 in a z-up world, read_tum's tuple, evenly sampled), as if everything
    else - the poses the cameras see, biases, gravity, extrinsics - were known exactly. Shifting
    a signal s(t) read with white noise of density q by dt changes it by s'(t) dt, so the
    information on dt is the integral of |s'|^2 / q^2: the gyroscope's s = w (rate in {I}), the
    accelerometer's s = f = R^T (a - g) (specific force in {I}, which turns with the rig).
    The cameras' own noise only adds to it: an estimate can reach the floor only with perfect
    cameras, and no estimator goes below it."""
    t_ns, p, R = truth
    t = (t_ns - t_ns[0]) * 1e-9
    dt = np.diff(t)
    # Rate in {I} at the midpoints, then its derivative at the inner samples.
    w = np.array([log_so3(R[i].T @ R[i + 1]) for i in range(len(t) - 1)]) / dt[:, None]
    t_mid = 0.5 * (t[:-1] + t[1:])
    w_dot = np.diff(w, axis=0) / np.diff(t_mid)[:, None]
    # Acceleration at the inner samples (second central difference), specific force in {I}.
    v = np.diff(p, axis=0) / dt[:, None]
    a = np.diff(v, axis=0) / np.diff(t_mid)[:, None]
    g = np.array([0.0, 0.0, -gravity])
    f = np.einsum("nji,nj->ni", R[1:-1], a - g)
    f_dot = np.diff(f, axis=0) / np.diff(t[1:-1])[:, None]
    step = np.mean(dt)
    information = (np.sum(w_dot ** 2) / gyro_noise_density ** 2
                   + np.sum(f_dot ** 2) / accel_noise_density ** 2) * step
    return float(1.0 / math.sqrt(information))


def base_imu_noise(truth_dir):
    """(gyroscope, accelerometer) noise densities of imu0 in TRUTH_DIR/kalibr_imu_chain.yaml."""
    with open(os.path.join(truth_dir, "kalibr_imu_chain.yaml")) as f:
        imu0 = yaml.safe_load(f)["imu0"]
    return float(imu0["gyroscope_noise_density"]), float(imu0["accelerometer_noise_density"])


def own_frame(result_dir, truth_dir):
    """Whether the estimate is in a frame of its own: the simulation had a board but the
    estimator ran without it (no aprilgrid.yaml in its result: tags as landmarks)."""
    return (os.path.exists(os.path.join(truth_dir, "aprilgrid.yaml"))
            and not os.path.exists(os.path.join(result_dir, "aprilgrid.yaml")))


def trajectory_metrics(result_dir, truth_dir):
    """ATE, RPE and pose NEES against the truth. An estimate in its own frame (own_frame) is
    first mapped onto the board frame through its first state, which defines that frame (the
    estimator holds it): positions, rotations and the covariances' position blocks; "board
    frame" figures are then after it and the pose covariance, relative to that state, matches."""
    truth = read_tum(os.path.join(truth_dir, "trajectory.tum"))
    t, p, R = read_tum(os.path.join(result_dir, "trajectory.tum"))
    mask, p_t, R_t = interpolate_truth(truth, t)
    t, p, R = t[mask], p[mask], R[mask]
    out = {"states": int(len(t)), "aligned_to_truth": own_frame(result_dir, truth_dir)}
    if os.path.exists(os.path.join(truth_dir, "kalibr_imu_chain.yaml")):
        out["time_offset_floor_s"] = time_offset_floor(truth, *base_imu_noise(truth_dir))
    R_a, t_a = np.eye(3), np.zeros(3)
    if out["aligned_to_truth"]:
        R_a = R_t[0] @ R[0].T
        t_a = p_t[0] - R_a @ p[0]
        p = p @ R_a.T + t_a
        R = np.array([R_a @ Re for Re in R])
    out["ate_position_m"], out["ate_orientation_rad"] = ate(p, R, p_t, R_t, aligned=False)
    out["ate_aligned_position_m"], out["ate_aligned_orientation_rad"] = ate(p, R, p_t, R_t,
                                                                            aligned=True)
    out["rpe_1s_translation_m"], out["rpe_1s_rotation_rad"] = rpe(t, p, R, p_t, R_t, 1.0)
    # The first seconds carry the initial calibration's error; the second half shows the
    # converged estimator.
    half = len(t) // 2
    out["ate_second_half_position_m"], out["ate_second_half_orientation_rad"] = ate(
        p[half:], R[half:], p_t[half:], R_t[half:], aligned=False)
    tc, pc, Rc, C = read_pose_covariance_csv(os.path.join(result_dir, "pose_covariance.csv"))
    mask, pc_t, Rc_t = interpolate_truth(truth, tc)
    if np.any(mask):
        pc = pc @ R_a.T + t_a
        Rc = np.array([R_a @ Re for Re in Rc])
        C = C.copy()
        for Ci in C:  # orientation errors are in the estimate's tangent: unchanged
            Ci[3:6, :] = R_a @ Ci[3:6, :]
            Ci[:, 3:6] = Ci[:, 3:6] @ R_a.T
        nees_R, nees_p = pose_nees(pc[mask], Rc[mask], C[mask], pc_t, Rc_t)
        out["nees_orientation"] = float(np.mean(nees_R))
        out["nees_position"] = float(np.mean(nees_p))
        out["nees_samples"] = int(np.sum(mask))
        out["nees_orientation_poses"], out["nees_position_poses"] = nees_R, nees_p
    return out


# ---------------------------------------------------------------- report


def markdown_report(table, metrics):
    lines = ["| sensor | quantity | final error | 3 sigma | inside 3 sigma |",
             "| --- | --- | ---: | ---: | --- |"]
    for r in table:
        inside = "held" if r["inside"] is None else "%d of %d axes" % (r["inside"], r["axes"])
        lines.append("| %s | %s [%s] | %.4f | %.4f | %s |" % (r["sensor"], r["quantity"], r["unit"],
                                                              r["error"], r["three_sigma"], inside))
    lines.append("")
    if metrics.get("aligned_to_truth"):
        lines.append("Estimated without the board: its frame is mapped onto the board's through "
                     "its first state, which defines it.")
        lines.append("")
    lines.append("| trajectory (%d states) | value |" % metrics["states"])
    lines.append("| --- | ---: |")
    lines.append("| ATE position, board frame [mm] | %.2f |" % (metrics["ate_position_m"] * 1e3))
    lines.append("| ATE orientation, board frame [deg] | %.3f |"
                 % math.degrees(metrics["ate_orientation_rad"]))
    lines.append("| ATE position, board frame, second half [mm] | %.2f |"
                 % (metrics["ate_second_half_position_m"] * 1e3))
    lines.append("| ATE orientation, board frame, second half [deg] | %.3f |"
                 % math.degrees(metrics["ate_second_half_orientation_rad"]))
    lines.append("| ATE position, SE(3)-aligned [mm] | %.2f |"
                 % (metrics["ate_aligned_position_m"] * 1e3))
    lines.append("| ATE orientation, SE(3)-aligned [deg] | %.3f |"
                 % math.degrees(metrics["ate_aligned_orientation_rad"]))
    lines.append("| RPE over 1 s, translation [mm] | %.2f |" % (metrics["rpe_1s_translation_m"] * 1e3))
    lines.append("| RPE over 1 s, rotation [deg] | %.3f |"
                 % math.degrees(metrics["rpe_1s_rotation_rad"]))
    if "time_offset_floor_s" in metrics:
        lines.append("| time offsets' floor from imu0's noise, all else known (1 sigma) [ms] | %.4f |"
                     % (metrics["time_offset_floor_s"] * 1e3))
    if "nees_orientation" in metrics:
        lines.append("| mean NEES orientation (3 dof, consistent: ~3) over %d poses | %.2f |"
                     % (metrics["nees_samples"], metrics["nees_orientation"]))
        lines.append("| mean NEES position (3 dof, consistent: ~3) | %.2f |"
                     % metrics["nees_position"])
    return "\n".join(lines) + "\n"


# ---------------------------------------------------------------- plots



def plot_errors(runs, path, title):
    """One figure for one sensor: per axis, the error and its +-3 sigma over time for every run
    in `runs` (a list of calibration_errors() entries of that sensor), like the report's Fig. 2.
    """
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    kind = runs[0]["kind"]
    quantities = [q for q in QUANTITIES if not (kind == "gyroscope" and q[0] == "translation")]
    fig, axes = plt.subplots(len(quantities), 3, figsize=(12, 2.6 * len(quantities)),
                             squeeze=False, sharex=True)
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for row, (name, cols, scale, unit) in enumerate(quantities):
        n_axes = cols.stop - cols.start
        for a in range(3):
            ax = axes[row][a]
            if a >= n_axes:
                ax.set_visible(False)
                continue
            for k, run in enumerate(runs):
                c = colors[k % len(colors)]
                e = run["error"][:, cols.start + a] * scale
                s = 3.0 * run["std"][:, cols.start + a] * scale
                ax.plot(run["t"], e, color=c, lw=1.0)
                ax.plot(run["t"], s, color=c, lw=0.8, ls="--")
                ax.plot(run["t"], -s, color=c, lw=0.8, ls="--")
            label = name if n_axes == 1 else "%s %s" % (name, AXES[a])
            ax.set_ylabel("%s [%s]" % (label, unit))
            ax.grid(True, alpha=0.3)
            # The first seconds (initial guess, before the first covariance) dwarf the rest.
            finals = [np.nanmax(np.abs(3.0 * r["std"][len(r["t"]) // 5:, cols.start + a]))
                      for r in runs]
            finals += [np.nanmax(np.abs(r["error"][len(r["t"]) // 5:, cols.start + a]))
                       for r in runs]
            lim = 1.3 * np.nanmax(finals) * scale if np.isfinite(np.nanmax(finals)) else None
            if lim and lim > 0:
                ax.set_ylim(-lim, lim)
    # Time labels under the lowest visible panel of each column.
    for a in range(3):
        visible = [axes[r][a] for r in range(len(quantities)) if axes[r][a].get_visible()]
        visible[-1].set_xlabel("time [s]")
        visible[-1].tick_params(labelbottom=True)
    fig.suptitle(title + " (solid: error, dashed: +-3 sigma)")
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)


INTRINSIC_NAMES = ("fu", "fv", "pu", "pv", "k1", "k2", "k3", "k4")
# A camera's: (first column, labels, grid rows, columns, scale, unit of the first four).
CAMERA_INTRINSICS = (7, INTRINSIC_NAMES, 2, 4, [1.0] * 8, ["px"] * 4 + [""] * 4)
# An rpng inertial sensor's: Tw, Ta, Tg [1e-3] and R_IMUtoACC [deg].
IMU_INTRINSICS = (15, IMU_INTRINSIC_KEYS, 4, 6, [1e3] * 21 + [180.0 / math.pi] * 3,
                  ["1e-3"] * 21 + ["deg"] * 3)


def intrinsics_estimated(run, kind=CAMERA_INTRINSICS):
    first, labels = kind[0], kind[1]
    return bool(np.any(run["std"][:, first:first + len(labels)] > 0.0))


def plot_intrinsics(runs, path, title, kind=CAMERA_INTRINSICS):
    """Intrinsics (a camera's [px] and distortion coefficients, or an IMU's Tw, Ta, Tg,
    R_IMUtoACC): error and +-3 sigma over time for every run, one panel per parameter."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    first, labels, n_rows, n_cols, scales, units = kind
    fig, axes = plt.subplots(n_rows, n_cols, figsize=(3.5 * n_cols, 2.6 * n_rows), sharex=True)
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for k, label in enumerate(labels):
        ax = axes[k // n_cols][k % n_cols]
        col, scale = first + k, scales[k]
        for i, run in enumerate(runs):
            c = colors[i % len(colors)]
            ax.plot(run["t"], scale * run["error"][:, col], color=c, lw=1.0)
            ax.plot(run["t"], 3.0 * scale * run["std"][:, col], color=c, lw=0.8, ls="--")
            ax.plot(run["t"], -3.0 * scale * run["std"][:, col], color=c, lw=0.8, ls="--")
        ax.set_ylabel("%s%s" % (label, " [%s]" % units[k] if units[k] else ""))
        ax.grid(True, alpha=0.3)
        tail = [np.nanmax(np.abs(np.concatenate([r["error"][len(r["t"]) // 5:, col],
                                                 3.0 * r["std"][len(r["t"]) // 5:, col]])))
                for r in runs]
        lim = 1.3 * scale * np.nanmax(tail)
        if np.isfinite(lim) and lim > 0:
            ax.set_ylim(-lim, lim)
    for ax in axes[-1]:
        ax.set_xlabel("time [s]")
    fig.suptitle(title + " (solid: error, dashed: +-3 sigma)")
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)


def evaluate(result_dir, truth_dir, out_dir):
    """Plots (one PNG per sensor), summary.md; returns (table rows, trajectory metrics)."""
    os.makedirs(out_dir, exist_ok=True)
    history = read_calibration_csv(os.path.join(result_dir, "calibration.csv"))
    errors = calibration_errors(history, read_truth_calibration(truth_dir))
    for name, e in errors.items():
        if not np.all(np.isnan(e["error"][:, 0:7])):  # the base IMU has no extrinsic
            plot_errors([e], os.path.join(out_dir, name + ".png"), "%s (%s)" % (name, e["kind"]))
        if intrinsics_estimated(e):
            plot_intrinsics([e], os.path.join(out_dir, name + "_intrinsics.png"),
                            "%s intrinsics" % name)
        if intrinsics_estimated(e, IMU_INTRINSICS):
            plot_intrinsics([e], os.path.join(out_dir, name + "_imu_intrinsics.png"),
                            "%s IMU intrinsics" % name, IMU_INTRINSICS)
    table = final_calibration_table(errors)
    metrics = trajectory_metrics(result_dir, truth_dir)
    with open(os.path.join(out_dir, "summary.md"), "w") as f:
        f.write(markdown_report(table, metrics))
    return table, metrics, errors
