#!/usr/bin/python3
"""Odometry latency through the nodelet, for scripts/bench (not a test).

A bag of tag detections and IMU readings is played at real-time speed (rosbag play) into
mvis_node while it solves; the node's own diagnostics ("mvis: odometry") give the latency from a
base reading's receipt to its odometry message (median and p99 over the run, the worst), the
largest interval between two odometry messages and between their readings' arrivals, and how far
the estimator's thread fell behind. Everything (roscore, the node, rosbag, this listener) runs on
the CPUs given, so "one core" means the node shares it with the player.

Usage: bench_odometry.py BIN_DIR CONFIG_DIR BAG PARAMS_YAML CPUS LABEL
  CPUS: a taskset list, e.g. 0 or 0,1.
"""
import os
import socket
import subprocess
import sys
import time

import rospy
from diagnostic_msgs.msg import DiagnosticArray
from nav_msgs.msg import Odometry


def free_port():
    with socket.socket() as s:
        s.bind(("localhost", 0))
        return s.getsockname()[1]


def main():
    bin_dir, config, bag, params = (os.path.abspath(p) for p in sys.argv[1:5])
    cpus, label = sys.argv[5:7]
    env = dict(os.environ)
    env["ROS_MASTER_URI"] = "http://localhost:%d" % free_port()
    os.environ.update(env)
    pin = ["taskset", "-c", cpus]
    procs = []
    try:
        procs.append(subprocess.Popen(pin + ["roscore", "-p", env["ROS_MASTER_URI"].split(":")[-1]],
                                      env=env, stdout=subprocess.DEVNULL,
                                      stderr=subprocess.DEVNULL))
        deadline = time.time() + 30
        while subprocess.run(["rosparam", "list"], env=env, capture_output=True).returncode != 0:
            if time.time() > deadline:
                raise RuntimeError("roscore did not start")
            time.sleep(0.3)
        subprocess.run(["rosparam", "load", params, "/mvis"], env=env, check=True)
        for key, value in [("config_dir", config), ("camera_input", "tag_detections"),
                           ("diagnostics_period", "1.0"), ("pixel_sigma", "0.5")]:
            subprocess.run(["rosparam", "set", "/mvis/" + key, value], env=env, check=True)
        log = open(os.path.join(env.get("ROS_HOME", "/tmp"), "bench_odometry_node.log"), "w")
        procs.append(subprocess.Popen(pin + [os.path.join(bin_dir, "mvis_node"), "__name:=mvis"],
                                      env=env, stdout=log, stderr=subprocess.STDOUT))
        rospy.init_node("bench_odometry", disable_signals=True)
        last = {}
        odometry = [0]
        behind = [0.0]

        def on_diagnostics(msg):
            for status in msg.status:
                if status.name == "mvis: odometry":
                    last.clear()
                    last.update({kv.key: float(kv.value) for kv in status.values})
                    behind[0] = max(behind[0], last["estimator_backlog_s"])

        rospy.Subscriber("/diagnostics", DiagnosticArray, on_diagnostics)
        rospy.Subscriber("/mvis/odometry", Odometry, lambda m: odometry.__setitem__(
            0, odometry[0] + 1))
        time.sleep(3.0)  # the node loads the rig and subscribes
        start = time.time()
        subprocess.run(pin + ["rosbag", "play", "--quiet", bag], env=env, check=True,
                       stdout=subprocess.DEVNULL)
        played_s = time.time() - start
        time.sleep(2.5)  # the last diagnostics
        if not last:
            raise RuntimeError("no odometry diagnostics from mvis_node")
        print("%s: %d odometry messages over a %.1f s replay; latency median %.2f ms, p99 %.2f "
              "ms, worst %.2f ms; worst interval %.2f ms (readings' %.2f ms); the estimator's "
              "thread behind by up to %.3f s (once a second), messages dropped %d"
              % (label, odometry[0], played_s, last["latency_p50_ms_since_start"],
                 last["latency_p99_ms_since_start"], last["worst_latency_ms"],
                 last["worst_interval_ms"], last["worst_reading_interval_ms"],
                 behind[0], last["messages_dropped_backlog_full"]))
    finally:
        for p in reversed(procs):
            p.terminate()
            try:
                p.wait(timeout=20)
            except subprocess.TimeoutExpired:
                p.kill()


if __name__ == "__main__":
    main()
