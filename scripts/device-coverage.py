#!/usr/bin/env python3
"""How often the 95 % intervals of a device fit hold the true values, over noise seeds.

The viscoelastic diaphragm of tests/device_calibration.rs (`diaphragm-visco` shortened: 6 radial
cells, stretched in 0.5 s and held 2 s, the mass hung over 1 s, 30 ms of the square wave) is run
once with the preset's first Maxwell branch; its pad deflection, with Gaussian noise of NOISE m
on every reading, is fitted for the branch's modulus and relaxation time, started 30 % off
(1.3 g1, 0.7 tau1), once per seed. Prints each seed's fit and intervals, then the count of
seeds whose intervals hold both true values.

usage: scripts/device-coverage.py [SEEDS [NOISE]]   (default 10 seeds, 2e-6 m)
environment: DEASIM (the binary, default target/release/deasim), OUT (a scratch directory)
Only the standard library is used.
"""
import csv
import json
import os
import random
import subprocess
import sys
import tempfile

SETS = [
    "mesh.radial=6",
    "prestretch.steps=8",
    "prestretch.duration=0.5",
    "prestretch.hold=2.0",
    "prestretch.hold_steps=4",
    "stages.1.duration=0.03",
    "output.plots=false",
    "output.fields_every=0",
    "solver.newton_rtol=1e-13",
]
# the preset vhb4910-wang2016's first branch (src/material/registry.rs)
G1, TAU1 = 26.06e3, 0.6074

FIT = """
[[parameters]]
path = "materials.vhb.branches.0.mu"
lower = 1e3
upper = 1e6
scale = "log"

[[parameters]]
path = "materials.vhb.branches.0.tau"
lower = 0.01
upper = 100.0
scale = "log"

[[objective]]
kind = "probe-misfit"
probe = "center_deflection"
stage = "load"
data = "pad.csv"
weight = 1e6

[[objective]]
kind = "probe-misfit"
probe = "center_deflection"
stage = "actuate"
data = "pad.csv"
weight = 1e6
"""


def run(args, cwd):
    r = subprocess.run(args, cwd=cwd, capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"{' '.join(args)} failed:\n{r.stderr}")
    return r


def main():
    seeds = int(sys.argv[1]) if len(sys.argv) > 1 else 10
    noise = float(sys.argv[2]) if len(sys.argv) > 2 else 2e-6
    deasim = os.path.realpath(os.environ.get("DEASIM", "target/release/deasim"))
    out = os.environ.get("OUT") or tempfile.mkdtemp()
    os.makedirs(out, exist_ok=True)
    sets = [a for s in SETS for a in ("--set", s)]
    base = run([deasim, "example", "diaphragm-visco"], out).stdout
    with open(os.path.join(out, "truth.toml"), "w") as f:
        f.write(base)
    run([deasim, "run", "truth.toml", "--out", "truth", "--overwrite"] + sets, out)
    with open(os.path.join(out, "truth", "history.csv")) as f:
        rows = [r for r in csv.DictReader(f)]
    with open(os.path.join(out, "fit.toml"), "w") as f:
        f.write(base + FIT)
    held = 0
    for seed in range(seeds):
        rng = random.Random(seed)
        # the hanging of the mass starts after the pre-stretch (0.5 + 2 s)
        lines = ["time,value", "2.5,0"]
        for r in rows:
            t = float(r["time"])
            if t > 2.5 + 1e-9 and r["stage"] in ("load", "actuate"):
                d = float(r["probe:center_deflection"]) + noise * rng.gauss(0.0, 1.0)
                lines.append(f"{t:.17e},{d:.17e}")
        with open(os.path.join(out, "pad.csv"), "w") as f:
            f.write("\n".join(lines) + "\n")
        start = ["--set", f"materials.vhb.branches.0.mu={1.3 * G1:e}",
                 "--set", f"materials.vhb.branches.0.tau={0.7 * TAU1:e}"]
        run([deasim, "calibrate", "fit.toml", "--out", f"fit{seed}", "--overwrite"]
            + sets + start, out)
        with open(os.path.join(out, f"fit{seed}", "calibration.json")) as f:
            cal = json.load(f)
        inside = True
        parts = []
        for path, truth in (("materials.vhb.branches.0.mu", G1),
                            ("materials.vhb.branches.0.tau", TAU1)):
            p = cal["parameters"][path]
            lo, hi = p["ci95"]
            inside &= lo <= truth <= hi
            parts.append(f"{path.split('.')[-1]} {p['fitted']:.4g} [{lo:.4g}, {hi:.4g}]")
        held += inside
        print(f"seed {seed}: {'; '.join(parts)}; rms {cal['rms']:.3g} m; "
              f"{cal['iterations']} it.; {'inside' if inside else 'OUTSIDE'}", flush=True)
    print(f"{held} of {seeds} seeds: both true values inside their 95 % intervals")


if __name__ == "__main__":
    main()
