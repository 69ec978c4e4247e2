#!/usr/bin/env bash
# The gradient's memory over a long dynamic history: `diaphragm-3d` (scenarios/) with the
# parameters C10, the viscosity, the pad's mass and the voltage amplitude, and a probe-misfit of
# its center deflection over the dynamic stage against a constant 1 mm, run by `deasim gradient`
# under `/usr/bin/time -v` for each budget given. Prints per budget: the forward and adjoint wall
# times, `peak_memory`, the budget, `recomputed_steps` (from gradient.json) and the max RSS; then
# whether J and the derivatives are the same numbers in every run.
#
# usage: scripts/gradient-memory.sh STEPS BUDGET [BUDGET ...]
#   STEPS   time steps of the dynamic stage (e.g. 10000)
#   BUDGET  a `--memory` size, e.g. "1 GiB" or "102.4 MiB"
# environment:
#   DT      the step size in s (default the example's 1e-3: 500 steps a period of its 2 Hz
#           square wave)
#   DEASIM  the deasim binary (default target/release/deasim)
#   OUT     scratch directory (default a new temporary one)
set -euo pipefail
if [ $# -lt 2 ]; then
    sed -n '2,15p' "$0"
    exit 2
fi
steps=$1
shift
deasim=$(realpath "${DEASIM:-target/release/deasim}")
scenarios=$(realpath "$(dirname "$0")/../scenarios")
out=${OUT:-$(mktemp -d)}
mkdir -p "$out"
cd "$out"
cp "$scenarios/diaphragm-3d.toml" d3.toml
cat >> d3.toml <<'EOF'

[[parameters]]
path = "materials.vhb.c10"
[[parameters]]
path = "materials.vhb.viscosity"
[[parameters]]
path = "loads.rigid.0.mass"
[[parameters]]
path = "electrodes.top.voltage.amplitude"

[[objective]]
kind = "probe-misfit"
probe = "center_deflection"
stage = "actuate"
data = "d.csv"
weight = 1e6
EOF
printf 'time,value\n0,1.0e-3\n1e6,1.0e-3\n' > d.csv
dt=${DT:-1e-3}
duration=$(python3 -c "print(repr($steps * $dt))")
i=0
for budget in "$@"; do
    i=$((i + 1))
    /usr/bin/time -v "$deasim" gradient d3.toml --set "stages.1.duration=$duration" \
        --set "stages.1.dt=$dt" \
        --set output.fields_every=0 --set output.plots=false --out "o$i" --overwrite \
        --memory "$budget" > "log$i" 2> "time$i"
    rss=$(grep 'Maximum resident' "time$i" | awk '{print $NF}')
    python3 - "o$i/gradient.json" "$budget" "$rss" <<'EOF'
import json, sys
d = json.load(open(sys.argv[1]))
print(f"budget {sys.argv[2]:>12}: forward {d['forward_s']:.1f} s, adjoint {d['adjoint_s']:.1f} s, "
      f"peak_memory {d['peak_memory'] / 1e6:.1f} MB (budget {d['memory_budget'] / 1e6:.1f} MB), "
      f"recomputed_steps {d['recomputed_steps']}, max RSS {int(sys.argv[3]) / 1e3:.1f} MB")
EOF
done
python3 - "$i" <<'EOF'
import json, sys
runs = [json.load(open(f"o{k}/gradient.json")) for k in range(1, int(sys.argv[1]) + 1)]
same = all(r["objective"] == runs[0]["objective"] and r["gradient"] == runs[0]["gradient"]
           for r in runs)
print("J and dJ/dp the same numbers in every run:", same)
EOF
