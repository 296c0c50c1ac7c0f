#!/usr/bin/env bash
# Tools.EncoderStartsWithHugePages: tools::start_with_huge_pages, through huge_pages_probe (which
# calls it as fmenc and fmbench do, then writes 64 MiB and prints its GLIBC_TUNABLES and its
# AnonHugePages in kB). Where the kernel gives transparent huge pages on request ("madvise"): by
# default the process runs again with glibc.malloc.hugetlb=1 and its 64 MiB are in huge pages; a
# tunable the user set is kept, the setting added after it; FACEMORPH_HUGE_PAGES=0, or the user's own
# glibc.malloc.hugetlb, or a start through the dynamic loader, leaves the process as started (no
# huge pages). Exits 77 (skipped) where the
# kernel's policy is not "madvise" or /proc/self/smaps_rollup is absent, naming which.
#   huge_pages_test.sh PROBE
set -uo pipefail
probe=${1:?usage: huge_pages_test.sh PROBE}
source "$(dirname "${BASH_SOURCE[0]}")/expect.sh"
policy=/sys/kernel/mm/transparent_hugepage/enabled
grep -q '\[madvise\]' "$policy" 2>/dev/null || { echo "SKIPPED: $policy is not [madvise]: $(cat "$policy" 2>/dev/null)"; exit 77; }
[[ -r /proc/self/smaps_rollup ]] || { echo "SKIPPED: no /proc/self/smaps_rollup"; exit 77; }

run() {  # run [VAR=VALUE...] [LOADER]: the probe's "TUNABLES HUGE_KB" under env -u GLIBC_TUNABLES and those
  env -u GLIBC_TUNABLES -u FACEMORPH_HUGE_PAGES "$@" "$probe" | cut -d' ' -f1,2
}
read -r tunables huge < <(run)
[[ $tunables == glibc.malloc.hugetlb=1 ]] || fail "by default: GLIBC_TUNABLES is '$tunables', not glibc.malloc.hugetlb=1"
((huge >= 32768)) || fail "by default: $huge kB of 64 MiB in huge pages"
read -r tunables huge < <(run GLIBC_TUNABLES=glibc.malloc.perturb=0)
[[ $tunables == glibc.malloc.perturb=0:glibc.malloc.hugetlb=1 ]] || fail "the user's tunable: GLIBC_TUNABLES is '$tunables'"
((huge >= 32768)) || fail "beside the user's tunable: $huge kB of 64 MiB in huge pages"
read -r tunables huge < <(run FACEMORPH_HUGE_PAGES=0)
[[ $tunables == - ]] || fail "FACEMORPH_HUGE_PAGES=0: GLIBC_TUNABLES is '$tunables'"
((huge == 0)) || fail "FACEMORPH_HUGE_PAGES=0: $huge kB in huge pages"
read -r tunables huge < <(run GLIBC_TUNABLES=glibc.malloc.hugetlb=0)
[[ $tunables == glibc.malloc.hugetlb=0 ]] || fail "the user's glibc.malloc.hugetlb=0: GLIBC_TUNABLES is '$tunables'"
((huge == 0)) || fail "the user's glibc.malloc.hugetlb=0: $huge kB in huge pages"
# Started through the dynamic loader, /proc/self/exe is the loader: not started again (the loader
# would take the probe's first argument for the program).
loader=$(ls /lib64/ld-linux-*.so.* /lib/ld-linux-*.so.* 2>/dev/null | head -1)
if [[ -n $loader ]]; then
  read -r tunables huge < <(run "$loader")
  [[ $tunables == - ]] || fail "through $loader: GLIBC_TUNABLES is '$tunables', not left alone"
fi
if ((failures > 0)); then
  echo "$failures failures" >&2
  exit 1
fi
echo "huge pages: all checks passed"
