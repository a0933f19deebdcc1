#!/usr/bin/env bash
# Mutation testing: applies each mutant of tests/mutants/ (a small patch of a kernel or of the
# host code) on its own to a copy of the tree, runs the tests the mutant names, and reports
# whether they killed it (at least one failed) or it survived. docs/testing.md says how to add
# a mutant and keeps the last report.
#
#   scripts/mutate.sh [--build DIR] [--work DIR] [--jobs N] [--list] [NAME...]
#
# NAME: a mutant's file name without .patch (default: every mutant). --build: the configured
# and built tree of this checkout (default build/), whose tests run the kernel-only mutants
# (kernel sources are read from $TANDEM_KERNEL_DIR when it is set, so those need no rebuild);
# `--build build-mutate/build` runs them on the copy's own build instead, leaving build/ free.
# The copy's build has no Python module (-DTANDEM_BUILD_PYTHON=OFF): name other tests too.
# --work: where the mutated copy of the sources and its own build live (default
# build-mutate/; the first host mutant builds it, later ones rebuild what their patch touches).
# Exit status: 0 when every mutant was killed, 1 when one survived, 2 on a usage error or a
# mutant that does not apply, build, or select any test.
#
# A mutant file starts with comment lines, then a unified diff (`git diff` of the repository
# root, applied with `git apply`):
#   # tests: <regular expression for ctest -R: the tests that must kill it>
#   # what: <one line: the defect it plants>
# Patches only of kernels/*.cl and kernels/path/ are kernel-only; any other file (kernels/shared
# headers are compiled into the host code too) makes it a host mutant.
set -euo pipefail

root=$(cd "$(dirname "$0")/.." && pwd)
build=$root/build
work=$root/build-mutate
jobs=2
list=0
names=()
while [[ $# -gt 0 ]]; do
    case $1 in
    --build) build=$(realpath -m "$2"); shift 2 ;;
    --work) work=$(realpath -m "$2"); shift 2 ;;
    --jobs) jobs=$2; shift 2 ;;
    --list) list=1; shift ;;
    -h | --help) sed -n '2,24p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    -*) echo "mutate.sh: unknown option $1" >&2; exit 2 ;;
    *) names+=("$1"); shift ;;
    esac
done

mutants_dir=$root/tests/mutants
if [[ ${#names[@]} -eq 0 ]]; then
    for f in "$mutants_dir"/*.patch; do names+=("$(basename "$f" .patch)"); done
fi
# field NAME KEY: the value of the mutant's "# KEY:" line
field() { sed -n "s/^# $2: *//p" "$mutants_dir/$1.patch" | head -n 1; }
# the files a patch touches
touched() { sed -n 's|^+++ b/||p' "$mutants_dir/$1.patch"; }
kernel_only() {
    local f
    while read -r f; do
        [[ $f == kernels/*.cl || $f == kernels/path/* ]] || return 1
    done < <(touched "$1")
}

for n in "${names[@]}"; do
    if [[ ! -f $mutants_dir/$n.patch ]]; then
        echo "mutate.sh: no mutant $n (tests/mutants/$n.patch)" >&2
        exit 2
    fi
    if [[ -z $(field "$n" tests) ]]; then
        echo "mutate.sh: tests/mutants/$n.patch: no '# tests:' line" >&2
        exit 2
    fi
done
if [[ $list -eq 1 ]]; then
    for n in "${names[@]}"; do
        kind=host
        kernel_only "$n" && kind=kernel
        printf '%-40s %-6s %s\n' "$n" "$kind" "$(field "$n" what)"
    done
    exit 0
fi
if [[ $build != "$work/build" && ! -x $build/tandem ]]; then
    echo "mutate.sh: $build has no tandem: build the tree first (README) or pass --build" >&2
    exit 2
fi

# The mutated copy: the checkout's tracked and untracked (not ignored) files, as they are now.
# Only files whose content differs are copied (and then stamped now), so that the copy's build
# rebuilds what changed, including what the last mutant's revert touched, and nothing else.
src=$work/src
mkdir -p "$src"
(cd "$root" && git ls-files -z --cached --others --exclude-standard) | python3 -c '
import filecmp, os, shutil, sys
root, src = sys.argv[1], sys.argv[2]
for rel in sys.stdin.buffer.read().decode().split("\0"):
    a, b = os.path.join(root, rel), os.path.join(src, rel)
    if not rel or not os.path.isfile(a):
        continue
    if not (os.path.isfile(b) and filecmp.cmp(a, b, shallow=False)):
        os.makedirs(os.path.dirname(b), exist_ok=True)
        shutil.copyfile(a, b)
        shutil.copymode(a, b)
' "$root" "$src"
[[ -d $src/.git ]] || git -C "$src" init -q # its own root, for git apply
configured=0
configure() {
    [[ $configured -eq 1 ]] && return 0
    cmake -S "$src" -B "$work/build" -DCMAKE_BUILD_TYPE=Release -DTANDEM_BUILD_PYTHON=OFF \
        >"$work/configure.log" 2>&1 || { echo "mutate.sh: configuring $work/build failed: $work/configure.log" >&2; exit 2; }
    configured=1
}

log=$work/logs
mkdir -p "$log"
# --build build-mutate/build: the kernel mutants run on the copy's own (unmutated) build, so that
# nothing runs in build/ meanwhile (the README's suite may run there at the same time)
if [[ $build == "$work/build" ]]; then
    configure
    cmake --build "$build" -j"$jobs" >"$log/build.log" 2>&1 ||
        { echo "mutate.sh: building $build failed: $log/build.log" >&2; exit 2; }
fi
survived=()
invalid=()
printf '%-40s %-6s %-9s %s\n' mutant kind result "failing tests (of those selected)"
for n in "${names[@]}"; do
    patch=$mutants_dir/$n.patch
    regex=$(field "$n" tests)
    if ! (cd "$src" && git apply --check "$patch" 2>"$log/$n.apply"); then
        printf '%-40s %-6s %-9s %s\n' "$n" - INVALID "does not apply: $log/$n.apply"
        invalid+=("$n")
        continue
    fi
    (cd "$src" && git apply "$patch")
    kind=host
    if kernel_only "$n"; then
        kind=kernel
        tree=$build
        env_args=(TANDEM_KERNEL_DIR="$src/kernels")
    else
        configure
        tree=$work/build
        env_args=()
        if ! cmake --build "$tree" -j"$jobs" >"$log/$n.build" 2>&1; then
            (cd "$src" && git apply -R "$patch")
            printf '%-40s %-6s %-9s %s\n' "$n" host INVALID "does not build: $log/$n.build"
            invalid+=("$n")
            continue
        fi
    fi
    set +e
    env "${env_args[@]}" ctest --test-dir "$tree" -R "$regex" -j"$jobs" --timeout 900 --output-on-failure \
        >"$log/$n.ctest" 2>&1
    rc=$?
    set -e
    (cd "$src" && git apply -R "$patch")
    failing=$(sed -n 's/^[[:space:]]*[0-9]* - \(.*\) (\(Failed\|Timeout\|SEGFAULT\|Subprocess aborted\|Exception\|Child aborted\).*/\1/p' \
        "$log/$n.ctest" | paste -sd ';' -)
    selected=$(sed -n 's/^.*tests passed, \([0-9]*\) tests failed out of \([0-9]*\)$/\2/p' "$log/$n.ctest")
    if grep -q "No tests were found" "$log/$n.ctest"; then
        printf '%-40s %-6s %-9s %s\n' "$n" "$kind" INVALID "'$regex' selects no test"
        invalid+=("$n")
    elif [[ $rc -ne 0 ]]; then
        printf '%-40s %-6s %-9s %s\n' "$n" "$kind" killed "$failing (of ${selected:-?})"
    else
        printf '%-40s %-6s %-9s %s\n' "$n" "$kind" SURVIVED "none of ${selected:-?}: $log/$n.ctest"
        survived+=("$n")
    fi
done
echo "${#names[@]} mutants: $((${#names[@]} - ${#survived[@]} - ${#invalid[@]})) killed," \
    "${#survived[@]} survived, ${#invalid[@]} invalid"
[[ ${#invalid[@]} -eq 0 ]] || exit 2
[[ ${#survived[@]} -eq 0 ]] || exit 1
