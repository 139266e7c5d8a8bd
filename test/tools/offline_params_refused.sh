#!/bin/bash
# mvis_offline --params with an unknown key or a bad value: refused at start (exit 2) with a
# message naming the file and the key. Usage: offline_params_refused.sh MVIS_OFFLINE
set -u
offline=$1
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
check() {  # FILE_CONTENT EXPECTED_MESSAGE
  printf '%s\n' "$1" > "$dir/params.yaml"
  out=$("$offline" --params "$dir/params.yaml" --config x --bag y --output z 2>&1)
  status=$?
  if [ "$status" -ne 2 ]; then echo "exit $status, expected 2: $out"; exit 1; fi
  if ! grep -qF "$dir/params.yaml: $2" <<< "$out"; then echo "unexpected message: $out"; exit 1; fi
}
check 'estimate_intrinsic: true' "unknown parameter 'estimate_intrinsic'"
check 'min_tags: 0' "parameter ~min_tags must be >= 1"
check 'ready_rotation_deg: 0' "parameter ~ready_rotation_deg must be positive"
echo "refused as expected"
