#!/usr/bin/env bash
# The scatter time of the one-view candidates of docs/scatter.md, "Sobol points and sparse
# multiple scatter": `tomograf project` of the AP view (the scene of scripts/scatter_seeds.py,
# seed 1) for each candidate and without scatter, three rounds taken in turn (none, c0, c1,
# c2, c3, none, …); prints each run's wall seconds. The scatter's time is a candidate's median
# less the no-scatter median (the CT's loading and the primary).
#
#   scripts/scatter_times.sh CT [BINARY] > times.txt    (run where nothing else runs)
#   ROUNDS=5 CANDIDATES="none c0 c2k" scripts/scatter_times.sh CT    (other rounds / candidates)
#
# c0: 14 000 histories, Latin hypercube; c1: 14 000, Sobol, split 4, sparse multiple;
# c2: 10 000, Sobol, split 8, sparse; c3: 20 000, Sobol, split 4, sparse; c0k and c1k: c0 and
# c1 with cell_check = 256 (docs/scatter.md, "Checking the cells"); c2k: 12 000, Sobol, split 4,
# sparse, cell_check = 256; c2500k: the same with 2 500 histories.
set -euo pipefail
ct=$(realpath "$1"); B=$(realpath "${2:-target/release/tomograf}")
work=$(mktemp -d); trap 'rm -rf "$work"' EXIT; cd "$work"
mk() { # name photons split sparse sampler [cell_check]
cat > $1.toml <<EOT
[volume]
path = "$ct"
[detector]
rows = 256
cols = 256
pitch_mm = [1.6796875, 1.6796875]
[views]
poses = ["ap"]
[acquisition]
preset = "kv-flat-panel-120kvp"
seed = 1
EOT
[ "$2" = 0 ] || cat >> $1.toml <<EOT
[scatter]
model = "monte-carlo"
photons = $2
split = $3
sparse_multiple = $4
sampler = "$5"
grid = 16
multiple_grid = 8
detection_cell_mm = 8.0
cell_check = ${6:-0}
images = ["scatter"]
EOT
cat >> $1.toml <<EOT
[output]
formats = ["npy"]
EOT
}
mk none 0; mk c0 14000 1 false latin-hypercube; mk c1 14000 4 true sobol; mk c2 10000 8 true sobol; mk c3 20000 4 true sobol
mk c0k 14000 1 false latin-hypercube 256; mk c1k 14000 4 true sobol 256
mk c2k 12000 4 true sobol 256; mk c2500k 2500 4 true sobol 256
for r in $(seq "${ROUNDS:-3}"); do for c in ${CANDIDATES:-none c0 c1 c2 c3 c0k c1k c2k}; do
  s=$(date +%s.%N); "$B" project --scene $c.toml -o out >/dev/null 2>&1; e=$(date +%s.%N)
  echo "$c $(python3 -c "print(round($e - $s, 3))")"; done; done
