#!/bin/bash
# mvis_offline gives the same bytes whatever --image-threads: a simulated small rig's rendered
# images (2 s) through one and three image threads, every result file compared.
# Usage: offline_threads_same.sh MVIS_SIMULATE MVIS_OFFLINE RIG_DIR
set -eu
simulate=$1 offline=$2 rig=$3
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
sed -e 's/^duration_s:.*/duration_s: 4/' "$rig/sim.yaml" > "$dir/sim.yaml"
"$simulate" --rig "$rig" --sim "$dir/sim.yaml" --output "$dir/data" > /dev/null
for n in 1 3; do
  "$offline" --config "$dir/data/config" --bag "$dir/data/sim.bag" --output "$dir/r$n" \
    --image-threads $n > "$dir/log$n" 2>&1
done
grep -q " image, " "$dir/log1"
status=0
for f in "$dir"/r1/*; do
  name=$(basename "$f")
  if ! cmp -s "$f" "$dir/r3/$name"; then echo "differs: $name"; status=1; fi
done
ls "$dir/r1" | wc -l | xargs echo "files compared:"
exit $status
