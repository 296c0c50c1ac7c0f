#!/usr/bin/env bash
# fmbench --capture --quick, the rate bench's smoke test: a small synthetic capture against Draco,
# Draco + JPEG, Draco + H.264 and the xyz variant, in one run. Asserts that every figure is there
# and sane (nothing on speed), that the report, its curves and pictures are written, and that a
# missing capture or a missing baseline program is a named error with a non-zero exit. Exits 77
# (ctest: skipped) when Debian's draco or ffmpeg is not installed.
#   bench_capture_test.sh FMBENCH
set -uo pipefail
fmbench=${1:?usage: bench_capture_test.sh FMBENCH}
for program in draco_encoder draco_decoder ffmpeg; do
  command -v "$program" >/dev/null || { echo "skipped: $program is not installed (tools/install-deps.sh)"; exit 77; }
done
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
source "$(dirname "${BASH_SOURCE[0]}")/expect.sh"

start=$(date +%s)
"$fmbench" --capture synth --quick --quiet --json "$work/bench.json" --report "$work/report/report.md" | tee "$work/stdout" ||
  fail "fmbench --capture synth --quick"
echo "fmbench --capture synth --quick: $(($(date +%s) - start)) s"
python3 - "$work/bench.json" <<'PY' || fail "the JSON's figures"
import json, math, sys
r = json.load(open(sys.argv[1]))["results"][0]
fm = r["facemorph"]
assert r["frames"] == 20 and fm["bytes"] > 0 and 0 < fm["bits_per_vertex_frame_geometry"] < fm["bits_per_vertex_frame"], fm
ev = fm["evaluation"]
assert len(ev["frames"]) == 20 and 0 < ev["held_out_rms_mean"] < 0.02, ev["held_out_rms_mean"]
assert 15 < fm["held_out_texture_psnr"] < 60 and fm["held_out_d1_psnr"] > 30, fm
# Per captured pixel (each disk texel weighted by the captured pixels it shows): the same frames'
# error, weighted otherwise, so near the disk's figure; and a share of the pixels in [0, 1].
assert abs(fm["held_out_texture_psnr_per_captured_pixel"] - fm["held_out_texture_psnr"]) < 3, fm
assert 0 <= fm["captured_pixels_under_a_texel"] <= 1, fm
# The disk shows the face once: the captured pixels its texels show are those the face's UVs cover.
assert abs(fm["captured_pixels_shown"] / fm["captured_pixels_of_the_face"] - 1) < 0.05, fm
names = {b["name"]: b for b in r["baselines"]}
assert set(names) == {"facemorph", "raw capture", "draco", "draco + jpeg", "draco + h264", "facemorph xyz"}, names.keys()
for name in ("draco", "draco + jpeg", "draco + h264"):
    b = names[name]
    assert b["geometry_bytes"] > 0 and 0 < b["rms_mean_relative"] < 0.05, b
for name in ("draco + jpeg", "draco + h264"):
    assert names[name]["texture_bytes"] > 0 and names[name]["texture_psnr_db"] > 15, names[name]
# The raw capture is far larger than its Draco geometry, and the ratios are what the bytes say.
assert names["raw capture"]["total_bytes"] > names["draco"]["total_bytes"]
assert math.isclose(r["ratios"]["geometry_vs_draco"], names["draco"]["geometry_bytes"] / (fm["bytes"] - sum(c["bytes"] for c in fm["chunks"] if c["type"] in ("TEXR", "TGOP"))), rel_tol=1e-9)
# Draco's error falls as its quantisation rises: the curve is measured, not assumed.
d = r["curves"]["draco_sample"]
assert d[0]["rms_mean"] > d[-1]["rms_mean"] and d[0]["bytes_per_frame"] < d[-1]["bytes_per_frame"], d
PY
for f in report.md synth_rd_geometry.png synth_rd_texture.png synth_frames.png synth_error.png; do
  [[ -s "$work/report/$f" ]] || fail "report: $f missing"
done
grep -q "geometry vs Draco" "$work/stdout" || fail "stdout lacks the targets"
grep -q "texture per captured pixel: PSNR held-out" "$work/stdout" || fail "stdout lacks the texture per captured pixel"
grep -q "| draco + h264 |" "$work/report/report.md" || fail "the report lacks the baselines table"

# --geometry-only: a file fmenc wrote, measured against its capture without mapping or baselines;
# its figures are the ones the JSON states, and it refuses to run without a file.
tools=$(dirname "$fmbench")
"$tools/fmsynth" -o "$work/cap" --frames 12 --fps 20 --vertices 2000 --noise 0 --texture-size 64 --quiet || fail "fmsynth"
"$tools/fmenc" "$work/cap" -o "$work/cap.fmv" --keyframes 25% --quiet || fail "fmenc"
"$fmbench" --capture "$work/cap" --fmv "$work/cap.fmv" --geometry-only --quiet --json "$work/geometry.json" | tee "$work/geometry.out" ||
  fail "fmbench --geometry-only"
python3 - "$work/geometry.json" "$(stat -c %s "$work/cap.fmv")" <<'PY' || fail "--geometry-only's figures"
import json, sys
r = json.load(open(sys.argv[1]))["results"][0]
ev = r["evaluation"]
assert r["bytes"] == int(sys.argv[2]), (r["bytes"], sys.argv[2])
assert len(ev["frames"]) == 12 and ev["keyframes"] >= 2, ev["keyframes"]
assert 0 < ev["keyframe_rms_mean"] < ev["held_out_rms_mean"] < 0.02, ev
PY
grep -q "held-out RMS" "$work/geometry.out" || fail "--geometry-only printed no summary"
expect_error "--geometry-only without a file" "it needs --fmv" "$fmbench" --capture "$work/cap" --geometry-only
"$tools/fmsynth" -o "$work/other" --frames 12 --fps 7 --vertices 2000 --noise 0 --texture-size 64 --quiet || fail "fmsynth (another capture)"
expect_error "--geometry-only with another capture's file" "made from another capture" "$fmbench" --capture "$work/other" --fmv "$work/cap.fmv" --geometry-only --quiet

expect_error "a missing capture" "capture '$work/none' does not exist" "$fmbench" --capture "$work/none" --quick
mkdir -p "$work/bin"
ln -s "$(command -v ffmpeg)" "$work/bin/ffmpeg"
expect_error "draco missing" "draco_encoder not found" env PATH="$work/bin" "$fmbench" --capture synth --quick
expect_error "nothing asked" "nothing to do" "$fmbench"

if ((failures > 0)); then
  echo "$failures failure(s)" >&2
  exit 1
fi
echo "fmbench --capture --quick: all checks passed"
