#!/usr/bin/env bash
# A real Slurm array job over a frame sequence (ctest label `slurm`): a one-node cluster on this
# machine (scripts/slurm-local), and the documented job script, examples/slurm/bloom-array.sbatch,
# submitted with `sbatch --array` and sparse ids over six frames, each task taking its shard with
# --shard auto; then merge, and every frame's bytes against a single-process run.
#   tests/cli/slurm_sequence.sh BLOOMREF SOURCE_DIR
# Exit 77 (skipped) without Slurm or root, unless BLOOMREF_REQUIRE_SLURM=1 (CI), which fails.
set -euo pipefail
bloomref=$1
src=$2
slurm_local=$src/scripts/slurm-local

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
mkdir -p bin shots
ln -s "$bloomref" bin/bloomref
export PATH="$work/bin:$PATH"  # sbatch passes the environment on to the tasks
# Six frames that all differ: five built-in scenes and the demo at another size.
i=1
for scene in demo impulse hot-edge threshold-tie constant; do
  bloomref scenes "$scene" --size 64x36 -o "$(printf 'shots/sh010.%04d.exr' "$i")" >/dev/null
  i=$((i + 1))
done
bloomref scenes demo --size 80x45 -o shots/sh010.0006.exr >/dev/null

# The documented script, on 6 frames instead of 240. Ids 0, 2, 4: three tasks with sparse ids
# (the shards 1/3, 2/3, 3/3), one CPU each.
sed 's/--frames 1-240/--frames 1-6/' "$src/examples/slurm/bloom-array.sbatch" >job.sh
timeout 120 sbatch --wait --array=0-4:2 --cpus-per-task=1 job.sh >sbatch.txt ||
  { echo "FAIL: sbatch --wait"; cat sbatch.txt bloom-*.log; exit 1; }

cd results
ls results-*.json | sort >files.txt
[ "$(wc -l <files.txt)" = 3 ] || { echo "FAIL: expected 3 results files"; cat files.txt; exit 1; }
grep -q '"source": "Slurm array (SLURM_ARRAY_TASK_ID=2, MIN 0, STEP 2, COUNT 3)"' results-2.json ||
  { echo "FAIL: task 2 did not record its Slurm shard"; cat results-2.json; exit 1; }
bloomref merge $(cat files.txt) --json merged.json || { echo "FAIL: merge"; exit 1; }
cd ..

mkdir -p single
bloomref run 'shots/sh010.####.exr' -o 'single/sh010.####.exr' -q
for f in 0001 0002 0003 0004 0005 0006; do
  cmp "out/sh010.$f.exr" "single/sh010.$f.exr" ||
    { echo "FAIL: frame $f differs from the single-process run"; exit 1; }
done
echo "PASS: 6 frames in 3 Slurm array tasks of examples/slurm/bloom-array.sbatch, merged, each frame the same bytes as one process"
