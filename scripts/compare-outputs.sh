#!/usr/bin/env bash
# Compares two folders written by scripts/record-outputs.sh, file by file and byte for byte.
# Images are compared by their pixels (idiff with a zero threshold: any difference, down to one
# ulp, fails), since image files carry a DateTime. Exits 0 when every output is identical, 1
# otherwise (naming each file that differs).
set -euo pipefail

if [[ $# -ne 2 ]]; then
    echo "usage: $0 DIR_A DIR_B" >&2
    exit 2
fi
a=$1
b=$2
status=0
count=0
# Same content: equal bytes, or for images equal pixels.
same() {
    cmp -s "$1" "$2" && return 0
    case "$1" in
    *.exr | *.png)
        idiff -fail 0 -failpercent 0 -warn 0 "$1" "$2" >/dev/null 2>&1
        ;;
    *) return 1 ;;
    esac
}
while IFS= read -r -d '' f; do
    rel=${f#"$a"/}
    count=$((count + 1))
    if [[ ! -f "$b/$rel" ]]; then
        echo "missing in $b: $rel"
        status=1
    elif ! same "$f" "$b/$rel"; then
        echo "differs: $rel"
        status=1
    fi
done < <(find "$a" -type f ! -name 'optimize*.json' -print0 | sort -z)
while IFS= read -r -d '' f; do
    rel=${f#"$b"/}
    [[ -f "$a/$rel" ]] || { echo "missing in $a: $rel"; status=1; }
done < <(find "$b" -type f ! -name 'optimize*.json' -print0)
if [[ $status -eq 0 ]]; then
    echo "all $count outputs bit-identical"
fi
exit $status
