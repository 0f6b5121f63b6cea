#!/usr/bin/env bash
# A real Slurm array job over a frame sequence (ctest label `slurm`): a one-node cluster on this
# machine (scripts/slurm-local), `sbatch --array` with sparse ids over six frames, each task
# taking its shard with --shard auto; then merge, and every frame's bytes against a
# single-process run of the same sequence.
#   tests/slurm_sequence.sh BLOOMREF SLURM_LOCAL
# Exit 77 (skipped) without Slurm or root, unless BLOOMREF_REQUIRE_SLURM=1 (CI), which fails.
set -euo pipefail
bloomref=$1
slurm_local=$2

skip() {
  if [ "${BLOOMREF_REQUIRE_SLURM:-}" = 1 ]; then
    echo "FAIL: $* (BLOOMREF_REQUIRE_SLURM=1)"
    exit 1
  fi
  echo "SKIP: $*"
  exit 77
}
for exe in sbatch slurmctld slurmd munged; do
  command -v "$exe" >/dev/null || skip "$exe not found (scripts/slurm-local install)"
done
[ "$(id -u)" -eq 0 ] || skip "the local cluster runs as root"

work=$(mktemp -d "${TMPDIR:-/tmp}/bloomref-slurm-test.XXXXXX")
cluster="$work/cluster"
# A port of this run's own, so that a cluster started by hand keeps its own.
export BLOOMREF_SLURM_PORT=$((20000 + $$ % 20000))
cleanup() {
  "$slurm_local" stop "$cluster" || true
  rm -rf "$work"
}
trap cleanup EXIT
eval "$("$slurm_local" start "$cluster")"

cd "$work"
# Six frames that all differ: five built-in scenes and the demo at another size.
i=1
for scene in demo impulse hot-edge threshold-tie constant; do
  "$bloomref" scenes "$scene" --size 64x36 -o "$(printf 'in.%04d.exr' "$i")" >/dev/null
  i=$((i + 1))
done
"$bloomref" scenes demo --size 80x45 -o in.0006.exr >/dev/null

cat >job.sh <<EOF
#!/bin/bash
exec "$bloomref" run "$work/in.####.exr" -o "$work/out.####.exr" --shard auto -q \\
     --json "$work/results-\$SLURM_ARRAY_TASK_ID.json"
EOF
chmod +x job.sh
# Ids 0, 2, 4: three tasks with sparse ids (the shards 1/3, 2/3, 3/3).
timeout 120 sbatch --wait --array=0-4:2 --output="$work/task-%a.log" job.sh >sbatch.txt ||
  { echo "FAIL: sbatch --wait"; cat sbatch.txt task-*.log; exit 1; }

ls results-*.json | sort >files.txt
[ "$(wc -l <files.txt)" = 3 ] || { echo "FAIL: expected 3 results files"; cat files.txt; exit 1; }
grep -q '"source": "Slurm array (SLURM_ARRAY_TASK_ID=2, MIN 0, STEP 2, COUNT 3)"' results-2.json ||
  { echo "FAIL: task 2 did not record its Slurm shard"; cat results-2.json; exit 1; }
"$bloomref" merge $(cat files.txt) --json merged.json ||
  { echo "FAIL: merge"; exit 1; }

"$bloomref" run "in.####.exr" -o "single.####.exr" -q
for f in 0001 0002 0003 0004 0005 0006; do
  cmp "out.$f.exr" "single.$f.exr" || { echo "FAIL: frame $f differs from the single-process run"; exit 1; }
done
echo "PASS: 6 frames in 3 Slurm array tasks, merged, each frame the same bytes as one process"
