#!/usr/bin/env bash
# Compares two folders written by scripts/record-outputs.sh, file by file and byte for byte.
# Exits 0 when every output is identical, 1 otherwise (naming each file that differs).
set -euo pipefail

if [[ $# -ne 2 ]]; then
    echo "usage: $0 DIR_A DIR_B" >&2
    exit 2
fi
a=$1
b=$2
status=0
count=0
while IFS= read -r -d '' f; do
    rel=${f#"$a"/}
    count=$((count + 1))
    if [[ ! -f "$b/$rel" ]]; then
        echo "missing in $b: $rel"
        status=1
    elif ! cmp -s "$f" "$b/$rel"; then
        echo "differs: $rel"
        status=1
    fi
done < <(find "$a" -type f ! -name optimize.json -print0 | sort -z)
while IFS= read -r -d '' f; do
    rel=${f#"$b"/}
    [[ -f "$a/$rel" ]] || { echo "missing in $a: $rel"; status=1; }
done < <(find "$b" -type f -print0)
if [[ $status -eq 0 ]]; then
    echo "all $count outputs bit-identical"
fi
exit $status
