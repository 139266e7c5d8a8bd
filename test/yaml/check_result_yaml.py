#!/usr/bin/python3
"""Every YAML file mvis writes reads in PyYAML (Kalibr's and ROS's Python) with its numbers as
numbers: a simulated small rig's configuration and truth (mvis_simulate) and an online result
(mvis_offline), every value walked, a string that is a number in disguise ("4e+02", which YAML 1.1
does not take as a float) failing the check.

Usage: check_result_yaml.py MVIS_SIMULATE MVIS_OFFLINE RIG_DIR
"""
import math
import os
import subprocess
import sys
import tempfile

import yaml


def strings_that_are_numbers(value, where, out):
    if isinstance(value, dict):
        for k, v in value.items():
            strings_that_are_numbers(v, where + "." + str(k), out)
    elif isinstance(value, list):
        for i, v in enumerate(value):
            strings_that_are_numbers(v, "%s[%d]" % (where, i), out)
    elif isinstance(value, str):
        try:
            float(value)
            out.append("%s: '%s' is a string" % (where, value))
        except ValueError:
            pass


def main(argv):
    simulate, offline, rig = argv[1:4]
    with tempfile.TemporaryDirectory() as tmp:
        subprocess.run([simulate, "--rig", rig, "--sim", os.path.join(rig, "sim.yaml"), "--output",
                        tmp, "--detections"], check=True, capture_output=True)
        result = os.path.join(tmp, "result")
        subprocess.run([offline, "--config", os.path.join(tmp, "config"), "--bag",
                        os.path.join(tmp, "sim.bag"), "--output", result], check=True,
                       capture_output=True)
        problems, files, numbers, stds = [], 0, 0, 0
        for sub in ("config", "truth", "result"):
            folder = os.path.join(tmp, sub)
            for name in sorted(os.listdir(folder)):
                if not name.endswith(".yaml"):
                    continue
                with open(os.path.join(folder, name)) as f:
                    data = yaml.safe_load(f)
                files += 1
                strings_that_are_numbers(data, sub + "/" + name, problems)
                numbers += sum(1 for _ in _floats(data))
                if sub == "result":
                    stds += sum(1 for k in _keys(data) if k.endswith("_std"))
        print("%d files, %d numbers, %d *_std keys in the result" % (files, numbers, stds))
        for p in problems:
            print("FAIL " + p)
        if problems or files < 7 or stds == 0:
            return 1
    return 0


def _floats(value):
    if isinstance(value, dict):
        for v in value.values():
            yield from _floats(v)
    elif isinstance(value, list):
        for v in value:
            yield from _floats(v)
    elif isinstance(value, float) and not math.isnan(value):
        yield value


def _keys(value):
    if isinstance(value, dict):
        for k, v in value.items():
            yield str(k)
            yield from _keys(v)
    elif isinstance(value, list):
        for v in value:
            yield from _keys(v)


if __name__ == "__main__":
    sys.exit(main(sys.argv))
