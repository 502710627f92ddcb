#!/usr/bin/env bash
# diagnose on records of one physics and growing length: the ladder it ends with, its time and peak memory.
# The physics plant (reference mode, core of the oracle's pressure_lag case, a hidden 0.1 s pressure lag),
# driven by random ramps and holds; records of 10^5, 10^6 and 10^7 samples (1.7 min, 17 min, 2.8 h at
# 1 kHz), and one of 2 and one of 30 minutes. Prints a Markdown table (docs/PERFORMANCE.md).
#   tools/length_scaling.sh [WORKDIR]        SIZES="100000 1000000" to limit the lengths
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
P="${PAMC:-$root/build/src/pamc}"
W="${1:-$(mktemp -d)}"; mkdir -p "$W"; cd "$W"
[ -x "$P" ] || { echo "length_scaling.sh: $P: not an executable (build first)" >&2; exit 2; }
[ -x /usr/bin/time ] || { echo "length_scaling.sh: /usr/bin/time missing (apt-get install time)" >&2; exit 2; }
cat > plant.json <<'EOF'
{"kind": "physics", "mode": "reference",
 "reference": {"k": 7.0, "rho": 1.2, "b": 19, "alpha": 1.0, "beta": 0.45, "gamma": 0.25},
 "effects": {"pressure_lag": {"tau": 0.1, "slew": 1000}},
 "stroke": {"min_mm": -1000, "max_mm": 1000}, "sensor": {"noise_std_mm": 0.005, "quantum_mm": 0.001}, "seed": 7}
EOF
"$P" emulate --plant plant.json --input random:32:-2.5:2.5 --duration 60 --out val.csv > /dev/null
echo "| record | samples | ladder | validated RMSE [mm] | wall time | peak memory |"
echo "|---|---|---|---|---|---|"
for n in ${SIZES:-100000 120000 1000000 1800000 10000000}; do
  s=$(python3 -c "print($n / 1000)")
  "$P" emulate --plant plant.json --input random:31:-2.5:2.5 --duration "$s" --out "r$n.csv" > /dev/null
  /usr/bin/time -f "%e %M" -o "t$n.txt" "$P" diagnose "r$n.csv" --validate val.csv --json "d$n.json" > /dev/null 2>&1
  read -r wall kb < "t$n.txt"
  python3 - "$n" "d$n.json" "$wall" "$kb" <<'PY'
import json, sys
n, path, wall, kb = int(sys.argv[1]), sys.argv[2], float(sys.argv[3]), int(sys.argv[4])
d = json.load(open(path))
final = [r for r in d["ladder"] if not r.get("probe")][-1]
print("| %.1f min | %d | %s | %.5f | %.1f s | %.0f MB |" % (n / 60000, n, " + ".join(final["effects"]) or "(none)",
                                                          final["rmse_val"], wall, kb / 1024))
PY
  rm -f "r$n.csv"
done
