#!/usr/bin/env bash
# Compares two folders written by scripts/record-outputs.sh, file by file and byte for byte.
# Images whose bytes differ (a header, say) are compared by their stored words (tandem-imgcmp:
# every float32 word, NaN payloads and the sign of zero included; $TANDEM_IMGCMP, else
# build/tandem-imgcmp). Exits 0 when every output is identical, 1 otherwise (naming each file that
# differs, and for an image its first differing word), 2 on a usage error.
set -euo pipefail

if [[ $# -ne 2 ]]; then
    echo "usage: $0 DIR_A DIR_B" >&2
    exit 2
fi
a=$1
b=$2
imgcmp=${TANDEM_IMGCMP:-$(dirname "$0")/../build/tandem-imgcmp}
if [[ ! -x $imgcmp ]]; then
    echo "$0: $imgcmp not found: build it (cmake --build build --target tandem-imgcmp) or set TANDEM_IMGCMP" >&2
    exit 2
fi
status=0
count=0
# Same content: equal bytes, or for images the same stored words (what differs printed).
same() {
    cmp -s "$1" "$2" && return 0
    case "$1" in
    *.exr | *.png)
        "$imgcmp" "$1" "$2" >&2
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
