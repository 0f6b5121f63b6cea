#!/usr/bin/env bash
# The job files of examples/ (docs/cluster.md) as their engines would run them, without the
# engines: each file's own bloomref command lines, run once per task with the variables that
# engine sets (Slurm array, Kubernetes Indexed Job, GitLab `parallel:`, a GitHub matrix, GNU
# parallel), then the file's merge. Every form must merge complete and give every frame the bytes
# of a single-process run. The files name 240 frames; this runs 10 (--frames 1-240 -> 1-10).
#   tests/cli/cluster_forms.sh BLOOMREF SOURCE_DIR
set -euo pipefail
bloomref=$1
src=$2
unset SLURM_ARRAY_TASK_ID JOB_COMPLETION_INDEX CI_NODE_INDEX TEST_SHARD_INDEX GTEST_SHARD_INDEX \
  BUILDKITE_PARALLEL_JOB CIRCLE_NODE_INDEX
work=$(mktemp -d "${TMPDIR:-/tmp}/bloomref-forms.XXXXXX")
trap 'rm -rf "$work"' EXIT
mkdir -p "$work/bin" "$work/shots"
ln -s "$bloomref" "$work/bin/bloomref"
export PATH="$work/bin:$PATH"

fail() { echo "FAIL: $*"; exit 1; }
# The bloomref (or mkdir ... && bloomref) command lines of a file, 10 frames instead of 240.
lines() { grep -o "$2.*" "$1" | sed 's/--frames 1-240/--frames 1-10/'; }

cd "$work"
i=1
for scene in demo impulse hot-edge threshold-tie constant; do
  for size in 48x40 40x48; do
    bloomref scenes "$scene" --size "$size" -o "$(printf 'shots/sh010.%04d.exr' "$i")" >/dev/null
    i=$((i + 1))
  done
done
mkdir -p single
bloomref run 'shots/sh010.####.exr' -o 'single/sh010.####.exr' --frames 1-10 -q

form() {  # name: a fresh folder with the shots, then "$@" runs the tasks in it
  local name=$1
  shift
  mkdir -p "$work/$name"
  ln -s "$work/shots" "$work/$name/shots"
  (cd "$work/$name" && "$@") >"$work/$name.log" 2>&1 || { cat "$work/$name.log"; fail "$name: a task failed"; }
  (cd "$work/$name" && bloomref merge results/results-*.json --json merged.json -q) ||
    fail "$name: merge found the shards incomplete"
  for f in single/*.exr; do
    cmp -s "$f" "$work/$name/out/$(basename "$f")" || fail "$name: $(basename "$f") differs from one process"
  done
  echo "ok: $name"
}

slurm() {  # sbatch --array=1-8: ids 1..8, as Slurm 22.05 sets the variables
  sed 's/--frames 1-240/--frames 1-10/' "$src/examples/slurm/bloom-array.sbatch" >job.sh
  for id in 1 2 3 4 5 6 7 8; do
    SLURM_ARRAY_TASK_ID=$id SLURM_ARRAY_TASK_MIN=1 SLURM_ARRAY_TASK_MAX=8 SLURM_ARRAY_TASK_STEP=1 \
      SLURM_ARRAY_TASK_COUNT=8 bash job.sh
  done
}
kubernetes() {  # completions: 8, JOB_COMPLETION_INDEX 0..7
  local cmd
  cmd=$(lines "$src/examples/kubernetes/bloom-indexed-job.yaml" "mkdir -p out results && bloomref run")
  [ -n "$cmd" ] || return 1
  for i in 0 1 2 3 4 5 6 7; do JOB_COMPLETION_INDEX=$i sh -c "$cmd"; done
}
gitlab() {  # parallel: 4, CI_NODE_INDEX 1..4
  local cmd
  cmd=$(lines "$src/examples/ci/gitlab-ci.yml" "bloomref run")
  [ -n "$cmd" ] || return 1
  for i in 1 2 3 4; do (mkdir -p out results && CI_NODE_INDEX=$i CI_NODE_TOTAL=4 sh -c "$cmd"); done
  sh -c "$(lines "$src/examples/ci/gitlab-ci.yml" "bloomref merge")"
}
github() {  # matrix.shard 1..4
  local cmd
  cmd=$(lines "$src/examples/ci/github-workflow.yml" "bloomref run")
  [ -n "$cmd" ] || return 1
  for k in 1 2 3 4; do (mkdir -p out results && sh -c "${cmd//\$\{\{ matrix.shard \}\}/$k}"); done
  GITHUB_STEP_SUMMARY=summary.md sh -c "$(lines "$src/examples/ci/github-workflow.yml" "bloomref merge")"
  grep -q "(merged): OK" summary.md
}
gnu_parallel() {  # GNU parallel when installed, else its substitution of {} by hand
  local cmd
  cmd=$(lines "$src/examples/parallel/bloom-parallel.sh" "^parallel -j")
  [ -n "$cmd" ] || return 1
  mkdir -p out results
  if command -v parallel >/dev/null; then
    sh -c "$cmd"
  else
    cmd=${cmd#parallel -j 2 }
    cmd=${cmd% ::: 1 2 3 4}
    for k in 1 2 3 4; do sh -c "${cmd//\{\}/$k}"; done
  fi
}

form slurm slurm
form kubernetes kubernetes
form gitlab gitlab
form github github
form gnu-parallel gnu_parallel
echo "PASS: the Slurm, Kubernetes, GitLab, GitHub and GNU parallel forms of examples/"
