# Sourced by scripts/prior_realistic.sh and scripts/prior_longer.sh (needs $bin and $out):
# the validation sets matched to the real CTs' statistics, the mixed checkpoint's training
# sets, and how a fine-tuned run keeps its parent's inference settings. Each set already
# made (its manifest written) is kept.

# val-real-lidc and val-real-fc: 6 phantoms each, matched to the five real CTs' measured
# statistics (docs/real-ct/validation-real-stats.md, "The sets").
val_real_sets() {
    local common="--size 64 --views 10 --split val --preset kv-flat-panel-120kvp --heterogeneity 60"
    [ -f "$out/val/val-real-lidc/manifest.jsonl" ] || $bin dataset -o "$out/val/val-real-lidc" \
        --phantoms 6 --seed 71000 --profile lidc --augment 16 $common
    [ -f "$out/val/val-real-fc/manifest.jsonl" ] || $bin dataset -o "$out/val/val-real-fc" \
        --phantoms 6 --seed 81000 --profile full-chest --augment 13 $common
}

# val-real-lidc-18 and val-real-fc-18 (decision 7): the same two populations, 18 phantoms
# each, seeds of their own (lidc 73000…, full-chest 83000…), made before any score on them.
val_real_sets_large() {
    local common="--size 64 --views 10 --split val --preset kv-flat-panel-120kvp --heterogeneity 60"
    [ -f "$out/val/val-real-lidc-18/manifest.jsonl" ] || $bin dataset -o "$out/val/val-real-lidc-18" \
        --phantoms 18 --seed 73000 --profile lidc --augment 16 $common
    [ -f "$out/val/val-real-fc-18/manifest.jsonl" ] || $bin dataset -o "$out/val/val-real-fc-18" \
        --phantoms 18 --seed 83000 --profile full-chest --augment 13 $common
}

# train_set NAME SEED PROFILE EXTRA…: 32 training phantoms (64³, 36 views) into $out/NAME.
train_set() {
    local name=$1 seed=$2 profile=$3; shift 3
    [ -f "$out/$name/manifest.jsonl" ] || $bin dataset -o "$out/$name" --phantoms 32 \
        --seed "$seed" --size 64 --views 36 --profile "$profile" --split train "$@"
}

# train-mixhet: the shipped mixed checkpoint's training set (32 lidc + 32 full-chest
# phantoms, and the same 64 with --augment 11 --heterogeneity 60).
train_mixhet() {
    train_set train-lidc 0 lidc
    train_set train-fc 300000 full-chest
    train_set train-ahet-lidc 0 lidc --augment 11 --heterogeneity 60
    train_set train-ahet-fc 300000 full-chest --augment 11 --heterogeneity 60
    [ -f "$out/train-mixhet/manifest.jsonl" ] || python3 scripts/merge_sets.py "$out/train-mixhet" \
        "$out/train-lidc" "$out/train-fc" "$out/train-ahet-lidc" "$out/train-ahet-fc"
}

# keep_parent_infer RUN_CONFIG PARENT_CONFIG: the fine-tuned run's config.toml becomes its
# parent's (inference settings included) with the run's own training iteration count; any
# other difference in the training settings is an error.
keep_parent_infer() {
    python3 - "$1" "$2" <<'EOF2'
import re, sys
mine, parent = (open(p).read() for p in sys.argv[1:3])
head = lambda t: t[: t.index("[infer]")]
same = lambda t: re.sub(r"(?m)^iterations = \d+$", "", head(t), count=1)
assert same(mine) == same(parent), "the training settings differ"
trained = re.search(r"(?m)^iterations = (\d+)$", mine).group(1)
open(sys.argv[1], "w").write(re.sub(r"(?m)^iterations = \d+$", f"iterations = {trained}", parent, count=1))
EOF2
}

# arm NAME PREFIX SETS…: scripts/validation_rule.py's argument for one candidate, NAME=the
# evaluation folders PREFIX+SET, comma-separated.
arm() { # NAME PREFIX SETS…
    local name=$1 prefix=$2 list=""
    shift 2
    for s in "$@"; do list="$list,$prefix$s"; done
    echo "$name=${list#,}"
}

# Decisions 10–12 (docs/real-ct/decision9-RULE.txt's sets and rule), with $probe, $bin,
# $out, $sets and $unwarped set by the caller.
# score_on_sets NAME CHECKPOINT [VIEWS]: TomoGRAF from VIEWS (default 1,2) on each set into
# $out/eval-NAME-SET.
score_on_sets() {
    for s in $sets; do
        [ -f "$out/eval-$1-$s/results.csv" ] || $bin evaluate "$probe/val/$s" \
            --checkpoint "$2" --views "${3:-1,2}" --no-baselines -o "$out/eval-$1-$s"
    done
}

# decide BASE BASE_PREFIX CANDIDATE CANDIDATE_PREFIX [one-view]: rule (i) over W and U, rule
# (ii) over U alone (with `one-view`, on the one-view rows only), into $out/decision.md.
decide() {
    local only=() tag=""
    [ "${5:-}" != one-view ] || { only=(--views 1); tag=", one view"; }
    # shellcheck disable=SC2086 # the set lists, word-split on purpose
    {
        echo "## Rule (i): W and U together$tag"
        python3 scripts/validation_rule.py "${only[@]}" "$(arm "$1" "$2" $sets)" "$(arm "$3" "$4" $sets)"
        echo "## Rule (ii): U alone$tag"
        python3 scripts/validation_rule.py "${only[@]}" "$(arm "$1" "$2" $unwarped)" "$(arm "$3" "$4" $unwarped)"
    } | tee "$out/decision.md"
}

# decision_setup PROBE_OUT OUT: what every decision script (decisions 9–17) starts with: $probe
# and $out as absolute paths (OUT made), the release binary built as $bin, and the shipped
# mixed checkpoint as $parent.
decision_setup() {
    probe=$(realpath "$1")
    mkdir -p "$2"
    out=$(realpath "$2")
    cargo build --release --quiet
    bin=$PWD/target/release/tomograf
    export MIMALLOC_PURGE_DELAY=-1
    parent=$PWD/model/checkpoints/lidc-full-chest
}

# variant DIR SED_SCRIPT: a copy of the shipped checkpoint ($parent) whose config.toml differs
# by the lines sed makes of SED_SCRIPT (decisions 18–20); kept if DIR exists.
variant() {
    [ -f "$1/config.toml" ] && return
    rm -rf "$1.tmp"
    cp -r "$parent" "$1.tmp"
    sed -i "$2" "$1.tmp/config.toml"
    mv "$1.tmp" "$1"
}

# Decisions 18–20's qualifying sets and rule, with $bin and $out set by the caller.
# qualifying_sets LIDC_SEED FC_SEED: six lidc (--augment 16) and six full-chest (--augment 13)
# validation phantoms from those seeds, made as scripts/prior_probe.sh makes its sets, as made
# (OUT/val/POP-base) and warped by 8 mm (OUT/val/POP-deform8).
qualifying_sets() {
    local common=(--size 64 --views 10 --split val --preset kv-flat-panel-120kvp --heterogeneity 60)
    local variant_flags vname vflags pop profile seed augment
    for variant_flags in "base" "deform8 --deform 8"; do
        read -r vname vflags <<< "$variant_flags"
        for pop in "lidc $1 16" "full-chest $2 13"; do
            read -r profile seed augment <<< "$pop"
            # shellcheck disable=SC2086 # vflags, word-split on purpose
            [ -f "$out/val/$profile-$vname/manifest.jsonl" ] || $bin dataset -o "$out/val/$profile-$vname" \
                --phantoms 6 --seed "$seed" --profile "$profile" --augment "$augment" "${common[@]}" $vflags
        done
    done
}
qualifying_warped="lidc-deform8 full-chest-deform8"
qualifying_unwarped="lidc-base full-chest-base"

# qualify_one_view NAME CHECKPOINT: TomoGRAF from one view on the qualifying sets into
# $out/eval-NAME-SET.
qualify_one_view() {
    local s
    for s in $qualifying_warped $qualifying_unwarped; do
        [ -f "$out/eval-$1-$s/results.csv" ] || $bin evaluate "$out/val/$s" \
            --checkpoint "$2" --views 1 --no-baselines -o "$out/eval-$1-$s"
    done
}

# qualify_rule CHOSEN_LINE PRIMES: rule (i) over the warped and as-made sets, rule (ii) over the
# as-made alone, q against r, into $out/decision.md; PRIMES names the sets (' or '').
qualify_rule() {
    # shellcheck disable=SC2086 # the set lists, word-split on purpose
    {
        echo "$1"
        echo "## Rule (i): W$2 and U$2 together"
        python3 scripts/validation_rule.py \
            "$(arm q "$out/eval-q-" $qualifying_warped $qualifying_unwarped)" \
            "$(arm r "$out/eval-r-" $qualifying_warped $qualifying_unwarped)"
        echo "## Rule (ii): U$2 alone"
        python3 scripts/validation_rule.py "$(arm q "$out/eval-q-" $qualifying_unwarped)" \
            "$(arm r "$out/eval-r-" $qualifying_unwarped)"
    } | tee "$out/decision.md"
}

# tuning_volumes SET ITEMS_DIR: per phantom of ITEMS_DIR, into $out/tune/SET/ID, what decisions
# 20 and 21's grid (scripts/decision20_grid.py) scores: the shipped networks' one-view volume
# without the blend (net.nii.gz; the checkpoint $out/net: $parent with mean_sweeps_weight 0), the
# four fits' spread (sd.nii.gz), the log with the volume's PSNR per view (net.log), and SART-TV
# from the mean alone (classical.nii.gz; $out/classical: one fit, the blend's weight 1
# everywhere). Two phantoms at a time on one thread each; each phantom done is kept.
tuning_volumes() {
    variant "$out/net" 's/^mean_sweeps_weight = .*/mean_sweeps_weight = 0.0/'
    variant "$out/classical" 's/^ensemble = 4$/ensemble = 1/; s/^mean_sweeps_weight = .*/mean_sweeps_weight = 1.0/; s/^mean_sweeps_spread = .*/mean_sweeps_spread = 0.0/'
    local items=("$2"/[0-9]*/) i
    for ((i = 0; i < ${#items[@]}; i += 2)); do
        tuning_phantom "$1" "${items[i]%/}" &
        if ((i + 1 < ${#items[@]})); then
            tuning_phantom "$1" "${items[i + 1]%/}" &
        fi
        wait
    done
}
tuning_phantom() { # SET ITEM_DIR
    local d=$out/tune/$1/$(basename "$2")
    [ -f "$d/classical.nii.gz" ] && return
    mkdir -p "$d"
    echo "$2" > "$d/item.txt"
    $bin --threads 1 reconstruct "$2" --checkpoint "$out/net" --views 1 -o "$d/net.nii.gz" \
        --spread "$d/sd.nii.gz" 2> "$d/net.log"
    $bin --threads 1 reconstruct "$2" --checkpoint "$out/classical" --views 1 --iterations 1 \
        -o "$d/classical.tmp.nii.gz" 2> "$d/classical.log"
    mv "$d/classical.tmp.nii.gz" "$d/classical.nii.gz"
}

# Decisions 20 and 21's q and r. require_decision18_q: stops unless $parent carries decision
# 18's blend (W = 0.5, S = 100 HU, no P), their q; since decision 21 the shipped checkpoint
# carries its r, so both scripts run from commit 41712143 (before it shipped).
require_decision18_q() {
    grep -q '"iteration": 72000' "$parent/state.json" \
        && grep -q '^mean_sweeps_weight = 0.5$' "$parent/config.toml" \
        && grep -q '^mean_sweeps_spread = 0.032552083333333336$' "$parent/config.toml" \
        && ! grep -q '^mean_sweeps_below_db' "$parent/config.toml" \
        || { echo "$parent is not decision 18's q (72 000 it., W = 0.5, S = 100 HU, no P): run this from commit 41712143, before decision 21 shipped its setting" >&2; exit 1; }
}

# grid_python: $py, the Python (PYTHON, default python3) that runs scripts/decision20_grid.py,
# checked for numpy and nibabel.
grid_python() {
    py=${PYTHON:-python3}
    "$py" -c "import numpy, nibabel" \
        || { echo "decision20_grid.py needs numpy and nibabel: PYTHON=/path/to/python" >&2; exit 1; }
}

# blend_variant DIR CHOSEN_LINE: q with the setting decision20_grid.py's "chosen: W = …, W2 = …,
# S = … HU, P = … dB" line names (S in normalised density: HU over the window's 3072 HU).
blend_variant() {
    local w w2 s_hu p_db s_norm w_f w2_f p_f
    read -r w w2 s_hu p_db < <(sed -E \
        's/^chosen: W = ([0-9.]+), W2 = ([0-9.]+), S = ([0-9.]+) HU, P = ([0-9.]+) dB.*/\1 \2 \3 \4/' <<< "$2")
    s_norm=$(python3 -c "print(repr($s_hu / 3072.0))")
    w_f=$(python3 -c "print(repr(float($w)))")
    w2_f=$(python3 -c "print(repr(float($w2)))")
    p_f=$(python3 -c "print(repr(float($p_db)))")
    variant "$1" "s/^mean_sweeps_weight = .*/mean_sweeps_weight = $w_f/; s/^mean_sweeps_spread = .*/mean_sweeps_spread = $s_norm/; \$a mean_sweeps_below_db = $p_f\nmean_sweeps_weight_below = $w2_f"
}
