#!/usr/bin/env bash
# Frame sequences: frames per second of one process against one process per frame, two shards
# at once against one process, and --jobs 1 against --jobs 2 at 256x256 and 3840x2160. Every
# timed run's outputs are compared byte for byte with the first configuration's, and the medians
# of REPEAT runs are printed (configurations alternate within each repeat, so that a change in
# the machine's load falls on all of them). Run by ctest (label benchmark):
#   benchmarks/sequence.sh BLOOMREF OUTDIR [processes|shards|hd|jobs|all]
# (hd: processes and shards, alternating in each repeat)
# Environment: FRAMES (default 240, 1920x1080), REPEAT (default 3), LARGE_FRAMES (default 12,
# 3840x2160), SMALL_FRAMES (default 240, 256x256).
set -euo pipefail
bloomref=$1
out=$2
what=${3:-all}
frames=${FRAMES:-240}
repeat=${REPEAT:-3}
large_frames=${LARGE_FRAMES:-12}
small_frames=${SMALL_FRAMES:-240}
dir="$out/sequence-bench"
rm -rf "$dir"
mkdir -p "$dir"
cd "$dir"

now() { date +%s%N; }
# median of the numbers on stdin
median() { sort -g | awk '{ v[NR] = $1 } END { print (NR % 2 ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2) }'; }
# seconds of a command, its output discarded
timed() {
  local t0 t1
  t0=$(now)
  "$@" >/dev/null
  t1=$(now)
  awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.3f\n", (b - a) / 1e9 }'
}
# A sequence of n frames of size s in folder d (one rendered frame, hard-linked: the same work
# per frame, little disk).
make_sequence() {
  local d=$1 s=$2 n=$3
  mkdir -p "$d"
  "$bloomref" scenes demo --size "$s" -o "$d/frame.exr" >/dev/null
  for ((f = 1; f <= n; f++)); do ln -f "$d/frame.exr" "$(printf '%s/in.%04d.exr' "$d" "$f")"; done
}
same_outputs() {  # two output folders hold the same bytes, frame for frame
  local a=$1 b=$2 f
  for f in "$a"/*.exr; do cmp -s "$f" "$b/$(basename "$f")" || { echo "FAIL: $f differs from $b"; exit 1; }; done
}
fps() { awk -v n="$1" -v s="$2" 'BEGIN { printf "%.2f", n / s }'; }
ratio() { awk -v a="$1" -v b="$2" 'BEGIN { printf "%.2f", a / b }'; }
echo "machine: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //'); load $(cut -d' ' -f1-3 /proc/loadavg)"

if [ "$what" = processes ] || [ "$what" = shards ] || [ "$what" = hd ] || [ "$what" = all ]; then
  make_sequence hd 1920x1080 "$frames"
  one=() many=() two=() two1=()
  for ((r = 1; r <= repeat; r++)); do
    rm -rf o1 && mkdir o1
    one+=("$(timed "$bloomref" run 'hd/in.####.exr' -o 'o1/out.####.exr' -q)")
    if [ "$what" != shards ]; then
      rm -rf oN && mkdir oN
      many+=("$(timed bash -c "for ((f = 1; f <= $frames; f++)); do n=\$(printf %04d \$f); \
        '$bloomref' run hd/in.\$n.exr -o oN/out.\$n.exr -q || exit 1; done")")
      same_outputs o1 oN
    fi
    if [ "$what" != processes ]; then
      rm -rf o2 && mkdir o2
      two+=("$(timed bash -c "'$bloomref' run 'hd/in.####.exr' -o 'o2/out.####.exr' -q --shard 1/2 & \
        '$bloomref' run 'hd/in.####.exr' -o 'o2/out.####.exr' -q --shard 2/2 & wait")")
      same_outputs o1 o2
      rm -rf o3 && mkdir o3
      two1+=("$(timed bash -c "'$bloomref' run 'hd/in.####.exr' -o 'o3/out.####.exr' -q --threads 1 --shard 1/2 & \
        '$bloomref' run 'hd/in.####.exr' -o 'o3/out.####.exr' -q --threads 1 --shard 2/2 & wait")")
      same_outputs o1 o3
    fi
  done
  rm -rf o1 oN o2 o3
  t_one=$(printf '%s\n' "${one[@]}" | median)
  echo "1920x1080 x $frames frames, one process:              ${t_one} s = $(fps "$frames" "$t_one") frames/s (runs: ${one[*]})"
  if [ "$what" != shards ]; then
    t_many=$(printf '%s\n' "${many[@]}" | median)
    echo "1920x1080 x $frames frames, a process per frame:      ${t_many} s = $(fps "$frames" "$t_many") frames/s (runs: ${many[*]}); one process is $(ratio "$t_many" "$t_one")x as fast"
  fi
  if [ "$what" != processes ]; then
    t_two=$(printf '%s\n' "${two[@]}" | median)
    t_two1=$(printf '%s\n' "${two1[@]}" | median)
    echo "1920x1080 x $frames frames, two shards at once:       ${t_two} s = $(fps "$frames" "$t_two") frames/s (runs: ${two[*]}); $(ratio "$t_one" "$t_two")x one process"
    echo "1920x1080 x $frames frames, two shards, --threads 1:  ${t_two1} s = $(fps "$frames" "$t_two1") frames/s (runs: ${two1[*]}); $(ratio "$t_one" "$t_two1")x one process"
  fi
  rm -rf hd
fi

if [ "$what" = jobs ] || [ "$what" = all ]; then
  for case in "256x256 $small_frames" "3840x2160 $large_frames"; do
    set -- $case
    size=$1 n=$2
    make_sequence "s$size" "$size" "$n"
    j1=() j2=()
    for ((r = 1; r <= repeat; r++)); do
      rm -rf a b && mkdir a b
      j1+=("$(timed "$bloomref" run "s$size/in.####.exr" -o 'a/out.####.exr' -q --jobs 1)")
      j2+=("$(timed "$bloomref" run "s$size/in.####.exr" -o 'b/out.####.exr' -q --jobs 2)")
      same_outputs a b
    done
    rm -rf a b "s$size"
    t1=$(printf '%s\n' "${j1[@]}" | median)
    t2=$(printf '%s\n' "${j2[@]}" | median)
    echo "$size x $n frames: --jobs 1 ${t1} s = $(fps "$n" "$t1") frames/s (runs: ${j1[*]}); --jobs 2 ${t2} s = $(fps "$n" "$t2") frames/s (runs: ${j2[*]}); jobs 2 / jobs 1 speed $(ratio "$t1" "$t2")"
  done
fi
echo "load after: $(cut -d' ' -f1-3 /proc/loadavg)"
