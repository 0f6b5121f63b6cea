#!/bin/bash
# Bloom over a frame sequence with GNU parallel (docs/cluster.md): four shards, two at a time,
# each on one thread (on a 2-core machine, two single-threaded shards at once keep both cores
# busy through the reading and writing of files). Add --sshlogin to spread them over machines
# that share the folder.
set -euo pipefail
mkdir -p out results
parallel -j 2 bloomref run 'shots/sh010.####.exr' -o 'out/sh010.####.exr' --frames 1-240 --threads 1 --shard {}/4 --json 'results/results-{}.json' ::: 1 2 3 4
bloomref merge results/results-*.json --json merged.json
