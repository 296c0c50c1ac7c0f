#!/usr/bin/env bash
# The command-line contract (design §4) end to end on a small synthetic capture: fmsynth -> fmenc ->
# fminfo -> fmdec, and the failures a user meets: each must exit non-zero, name the file and the
# reason, and leave no file (and no earlier file changed).
#   cli_test.sh TOOLS_DIR
set -uo pipefail
tools=${1:?usage: cli_test.sh TOOLS_DIR}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
source "$(dirname "${BASH_SOURCE[0]}")/expect.sh"

"$tools/fmsynth" -o "$work/cap" --frames 8 --fps 20 --vertices 2000 --remesh --noise 0 --texture-size 64 --quiet || fail "fmsynth"
"$tools/fmenc" "$work/cap" -o "$work/a.fmv" --grid 33 --representation hl+t --texture 64 --keyframes 30% --quiet || fail "fmenc"
[[ -s "$work/a.fmv" ]] || fail "fmenc wrote nothing"
"$tools/fminfo" "$work/a.fmv" >"$work/info" || fail "fminfo"
grep -q "format 2.1" "$work/info" || fail "fminfo does not name the format"
grep -q "^texture  *64x64 AVIF image sequence per group" "$work/info" || fail "fminfo does not say the textures are one AV1 sequence per group (the default)"
"$tools/fmenc" "$work/cap" -o "$work/stills.fmv" --grid 33 --texture 64 --keyframes 30% --texture-coding stills --quiet || fail "fmenc --texture-coding stills"
"$tools/fminfo" "$work/stills.fmv" | grep -q "^texture  *64x64 AVIF still per keyframe" || fail "fmenc --texture-coding stills did not write stills"
"$tools/fmenc" "$work/cap" -o "$work/x.fmv" --texture-coding films --quiet 2>"$work/err" && fail "fmenc accepted --texture-coding films"
grep -q "texture coding 'films'" "$work/err" || fail "fmenc does not name a wrong --texture-coding"
"$tools/fminfo" "$work/a.fmv" --json >"$work/info.json" || fail "fminfo --json"
python3 -c "import json,sys; d=json.load(open(sys.argv[1])); assert d['grid']['n']==33 and len(d['keyframes'])>=2" "$work/info.json" ||
  fail "fminfo --json is not the file's description"
# fminfo decodes nothing (each group's fields bytes, from the index); --verify decodes every keyframe
# and divides each group's bytes among its keyframes.
grep -q "checksums verified (fminfo --verify decodes" "$work/info" || fail "fminfo does not say it decoded nothing"
"$tools/fminfo" "$work/a.fmv" --json --verify >"$work/verified.json" || fail "fminfo --json --verify"
python3 -c "import json,sys
d, v = (json.load(open(p)) for p in sys.argv[1:3])
assert not d['verified'] and v['verified'], 'verified'
assert all('fields_bytes' not in k for k in d['keyframes']), 'fields bytes without --verify'
assert d['field_groups'] == v['field_groups'] and d['field_groups'], 'groups'
for g in v['field_groups']:
    assert sum(k['fields_bytes'] for k in v['keyframes'][g['first']:g['first'] + g['count']]) == g['bytes'], g
assert sum(g['bytes'] for g in d['field_groups']) == sum(c['bytes'] for c in d['chunks'] if c['type'] in ('KGOP', 'KGLV')), 'KGOP'" \
  "$work/info.json" "$work/verified.json" || fail "fminfo --verify's bytes per keyframe do not add up to its groups'"

# Re-coding (spec/method.md §5.3; a group is a KGOP or, where the levels predictor pays, format 2.6's KGLV): --field-error auto keeps the file's steps, so its fields' bytes
# stay; a given target rounds them again. fminfo --field-bytes estimates those bytes array by array.
kgop() { python3 -c "import json,sys; print(sum(c['bytes'] for c in json.load(sys.stdin)['chunks'] if c['type'] in ('KGOP', 'KGLV')))"; }
"$tools/fmenc" "$work/a.fmv" -o "$work/kept.fmv" --quiet || fail "fmenc re-coding a file"
"$tools/fmenc" "$work/a.fmv" -o "$work/coarser.fmv" --field-error 0.3% --quiet || fail "fmenc re-coding a file at 0.3%"
a_bytes=$("$tools/fminfo" "$work/a.fmv" --json | kgop)
[[ $("$tools/fminfo" "$work/kept.fmv" --json | kgop) == "$a_bytes" ]] || fail "re-coding at auto changed the fields' bytes"
(( $("$tools/fminfo" "$work/coarser.fmv" --json | kgop) < a_bytes )) || fail "re-coding at 0.3% did not round the fields again"
# Kept steps, regrouped: a given --intra-period is honoured (each keyframe its own group), auto
# keeps the file's groups.
groups() { python3 -c "import json,sys; d=json.load(sys.stdin); print(len(d['field_groups']), len(d['keyframes']))"; }
"$tools/fmenc" "$work/a.fmv" -o "$work/regrouped.fmv" --intra-period 1 --quiet || fail "fmenc re-coding a file with --intra-period 1"
read -r regrouped keyframes < <("$tools/fminfo" "$work/regrouped.fmv" --json | groups)
((regrouped == keyframes && keyframes > 1)) || fail "re-coding at auto with --intra-period 1 left $regrouped groups for $keyframes keyframes"
[[ $("$tools/fminfo" "$work/kept.fmv" --json | groups) == $("$tools/fminfo" "$work/a.fmv" --json | groups) ]] ||
  fail "re-coding at auto did not keep the file's groups"
# A 16-bit file states its steps too (a 65535th of each array's range): auto keeps them.
"$tools/fmenc" "$work/a.fmv" -o "$work/a16.fmv" --field-error 0 --quiet || fail "fmenc re-coding a file at 16 bits"
"$tools/fmenc" "$work/a16.fmv" -o "$work/a16-kept.fmv" --quiet || fail "fmenc re-coding a 16-bit file"
[[ $("$tools/fminfo" "$work/a16-kept.fmv" --json | kgop) == $("$tools/fminfo" "$work/a16.fmv" --json | kgop) ]] ||
  fail "re-coding a 16-bit file at auto changed its fields' bytes"
"$tools/fminfo" "$work/a.fmv" --json --field-bytes | python3 -c "import json,sys
d = json.load(sys.stdin); kgop = sum(c['bytes'] for c in d['chunks'] if c['type'] in ('KGOP', 'KGLV'))
parts = {g['arrays']: g['bytes'] for g in d['field_bytes_by_array']}
assert parts['H'] > 0 and parts['log lambda'] > 0 and parts['positions'] == 0, parts
assert abs(sum(parts.values()) / kgop - 1) < 0.1, (sum(parts.values()), kgop)" || fail "fminfo --field-bytes does not add up to the KGOP chunks"
# --field-bytes opens the file once for both its estimate and the description (spec/container.md
# §10.5): with and without --verify, the rest of what it prints is what fminfo prints without it.
for verify in "" --verify; do
  "$tools/fminfo" "$work/a.fmv" --json $verify >"$work/plain.json" && "$tools/fminfo" "$work/a.fmv" --json --field-bytes $verify >"$work/costed.json" &&
    python3 -c "import json,sys
plain, costed = (json.load(open(p)) for p in sys.argv[1:3])
assert costed.pop('field_bytes_by_array') and costed == plain, (plain, costed)" "$work/plain.json" "$work/costed.json" ||
    fail "fminfo --field-bytes $verify: its description is not fminfo $verify's"
done
# Each group holds its arrays' values (H, log lambda, a, b: one a node of G's interior; the band
# three a fixed node; the rim three a rim node), and a keyframe is costed from the one before only
# inside a group: the same codes, each keyframe its own group (regrouped.fmv, above), cost more.
"$tools/fminfo" "$work/a.fmv" --json --field-bytes >"$work/bytes.json" && "$tools/fminfo" "$work/regrouped.fmv" --json --field-bytes >"$work/bytes1.json" &&
  python3 -c "import json,sys
d, one = (json.load(open(p)) for p in sys.argv[1:3])
g, k = d['grid'], len(d['keyframes'])
values = {a['arrays']: a['values'] for a in d['field_bytes_by_array']}
interior = k * (g['nodes'] - g['rim_nodes'])
assert values == {'H': interior, 'log lambda': interior, 'a': interior, 'b': interior, 'band': 3 * k * g['fixed_nodes'],
                  'positions': 0, 'rim': 3 * k * g['rim_nodes'], 'hole level': 0}, values
total = lambda doc: sum(a['bytes'] for a in doc['field_bytes_by_array'])
assert len(one['field_groups']) == k > 1 and len(d['field_groups']) < k, (d['field_groups'], one['field_groups'])
assert total(one) > 1.05 * total(d), (total(one), total(d))" "$work/bytes.json" "$work/bytes1.json" ||
  fail "fminfo --field-bytes: its arrays' values, or its keyframes' prediction within a group, are not the file's"
# Segments (spec/part-file.md §7): measured, assembled and joined by fmcat into a file fminfo takes;
# what a user gets wrong is refused by name, and a refused join writes nothing.
seg=(--grid 33 --texture 64 --keyframes 30% --intra-period 1 --quiet)
"$tools/fmenc" "$work/cap" --stage sample --frames 0:8 -o "$work/all.fms" "${seg[@]}" || fail "fmenc --stage sample"
for s in 0 1; do
  "$tools/fmenc" --stage measure "$work/all.fms" --segment "$s/2" -o "$work/m$s.json" "${seg[@]}" || fail "fmenc --stage measure $s/2"
done
for s in 0 1; do
  "$tools/fmenc" --stage assemble "$work/all.fms" --segment "$s/2" --measures "$work/m0.json,$work/m1.json" -o "$work/seg$s.fmv" "${seg[@]}" ||
    fail "fmenc --stage assemble --segment $s/2"
done
"$tools/fmcat" "$work/seg1.fmv" "$work/seg0.fmv" -o "$work/joined.fmv" --check --quiet || fail "fmcat"
"$tools/fminfo" "$work/joined.fmv" >/dev/null || fail "fminfo does not take the joined file"
expect_error "a segment missing" "segment 1 of 2 is missing" "$tools/fmcat" "$work/seg0.fmv" -o "$work/half.fmv"
[[ ! -e $work/half.fmv ]] || fail "a refused join wrote a file"
expect_error "a file that is no segment" "a.fmv: it is not a segment" "$tools/fmcat" "$work/seg0.fmv" "$work/a.fmv" -o "$work/half.fmv"
expect_error "measure without a segment" "--stage measure needs --segment" "$tools/fmenc" --stage measure "$work/all.fms" -o "$work/m.json"
expect_error "a segment without measures" "needs --measures" "$tools/fmenc" --stage assemble "$work/all.fms" --segment 0/2 -o "$work/s.fmv"
expect_error "a bad segment" "S/N" "$tools/fmenc" --stage measure "$work/all.fms" --segment 2/2 -o "$work/m.json"
expect_error "a measure missing" "no measure of segment 1/2" "$tools/fmenc" --stage assemble "$work/all.fms" --segment 0/2 --measures "$work/m0.json" -o "$work/s.fmv" "${seg[@]}"
# --stage check refuses a part sampled with other settings by the assemble's own check (check_part_settings).
"$tools/fmenc" --stage check "$work/all.fms" --capture "$work/cap" "${seg[@]}" || fail "fmenc --stage check"
expect_error "a part checked against other settings" "was sampled with other settings than these" \
  "$tools/fmenc" --stage check "$work/all.fms" --capture "$work/cap" "${seg[@]}" --registration moebius

# One frame: mesh, material, texture, picture.
"$tools/fmdec" "$work/a.fmv" --t 0.17 -o "$work/f.obj" --preview "$work/f_view.png" --quiet || fail "fmdec --t"
for f in f.obj f.mtl f.png f_view.png; do [[ -s "$work/$f" ]] || fail "fmdec did not write $f"; done
"$tools/fmdec" "$work/a.fmv" --t 0.17 -o "$work/f.ply" --quiet || fail "fmdec -o .ply"
# A range: to nothing (timing), to a folder; the keyframes' fields as EXR.
"$tools/fmdec" "$work/a.fmv" --fps 20 --null >"$work/null" || fail "fmdec --null"
grep -q "ms per frame" "$work/null" || fail "fmdec --null reports no speed"
"$tools/fmdec" "$work/a.fmv" --fps 20 --from 0.1 --to 0.2 --out-dir "$work/seq" --quiet || fail "fmdec --out-dir"
[[ $(ls "$work/seq"/*.obj | wc -l) -eq 3 ]] || fail "fmdec --out-dir: not 3 frames"
"$tools/fmdec" "$work/a.fmv" --fps 20 --from 0.1 --to 0.2 --preview "$work/range.mp4" --quiet || fail "fmdec --preview .mp4"
[[ -s "$work/range.mp4" && ! -e "$work/range.partial.mp4" ]] || fail "fmdec --preview .mp4 wrote no video"
"$tools/fmdec" "$work/a.fmv" --extract-fields "$work/fields" --quiet || fail "fmdec --extract-fields"
ls "$work/fields"/keyframe_000.exr >/dev/null || fail "no EXR"

# Failures.
expect_error "t past the sane range" "outside the range this sequence can serve" "$tools/fmdec" "$work/a.fmv" --t 99 -o "$work/late.obj"
[[ ! -e "$work/late.obj" ]] || fail "a failed decode left late.obj"
"$tools/fmdec" "$work/a.fmv" --t 99 --clamp -o "$work/late.obj" --quiet || fail "--clamp"
head -c 3000 "$work/a.fmv" >"$work/cut.fmv"
expect_error "truncated file" "truncated" "$tools/fmdec" "$work/cut.fmv" --t 0.1 -o "$work/cut.obj"
expect_error "truncated file (fminfo)" "cut.fmv" "$tools/fminfo" "$work/cut.fmv"
cp "$work/a.fmv" "$work/flip.fmv"
# Zeros in the middle of the file: inside a texture's payload, which only its checksum can catch.
printf '\x00\x00\x00\x00' | dd of="$work/flip.fmv" bs=1 seek=$(($(stat -c %s "$work/a.fmv") / 2)) conv=notrunc status=none
expect_error "corrupted file" "checksum" "$tools/fmdec" "$work/flip.fmv" --t 0.1 -o "$work/flip.obj"
# Re-coding it (the writer reads the input a keyframe at a time) fails naming the input alone, not
# the output it was making, and writes nothing.
expect_error "re-coding a corrupted file" "error (corrupt): $work/flip.fmv: checksum" "$tools/fmenc" "$work/flip.fmv" -o "$work/flip-recoded.fmv" --quiet
[[ ! -e "$work/flip-recoded.fmv" ]] || fail "a failed re-code wrote flip-recoded.fmv"
expect_error "preview over the texture" "give the preview another name" "$tools/fmdec" "$work/a.fmv" --t 0.1 -o "$work/g.obj" --preview "$work/g.png"
expect_error "glTF of one time" "a glTF clip is a range" "$tools/fmdec" "$work/a.fmv" --t 0.1 -o "$work/clip.glb"
# Frame counts are range-checked before the cast to int (1e300 s at 30 fps was undefined behaviour).
expect_error "a rate past int" "more than 10^8 frames" "$tools/fmdec" "$work/a.fmv" --fps 1e300 --null
expect_error "a range past int" "more than 10^8 frames" "$tools/fmdec" "$work/a.fmv" --fps 30 --to 1e300 --clamp --null
expect_error "a file over --max-memory" "over the memory limit of 16.0 KiB" "$tools/fminfo" "$work/a.fmv" --max-memory 16K
expect_error "a bad --max-memory" "is not a size" "$tools/fmdec" "$work/a.fmv" --fps 20 --null --max-memory 12X
"$tools/fmdec" "$work/a.fmv" --fps 20 -o "$work/clip.glb" --quiet || fail "fmdec -o clip.glb"
[[ $(head -c 4 "$work/clip.glb") == "glTF" ]] || fail "clip.glb is not a glTF binary"
expect_error "not a container" "not a facemorph container" "$tools/fmdec" "$work/cap/frame_0000.obj" --t 0.1 -o "$work/x.obj"
# An encode that fails keeps the earlier file and leaves nothing behind.
cp "$work/a.fmv" "$work/before.fmv"
mv "$work/cap/frame_0003.jpg" "$work/hidden.jpg"
expect_error "missing texture (--strict)" "frame_0003" "$tools/fmenc" "$work/cap" -o "$work/a.fmv" --grid 33 --texture 64 --quiet --strict
cmp -s "$work/a.fmv" "$work/before.fmv" || fail "a failed encode changed the earlier file"
[[ $(ls "$work" | grep -c '\.tmp') -eq 0 ]] || fail "a failed encode left a temporary file"
# Without --strict the frame is dropped, named in fmenc's summary and in fminfo.
"$tools/fmenc" "$work/cap" -o "$work/dropped.fmv" --grid 33 --texture 64 >"$work/dropped.txt" 2>&1 || fail "fmenc does not drop a frame without its texture"
grep -q "1 of 8 frames dropped" "$work/dropped.txt" || fail "fmenc's summary does not count the dropped frame"
grep -q "frame_0003.obj (frame 3, 0.150 s):.*frame_0003" "$work/dropped.txt" || fail "fmenc's summary does not name the dropped frame and why"
"$tools/fminfo" "$work/dropped.fmv" >"$work/dropped.info" || fail "fminfo of a file with a dropped frame"
grep -q "^dropped     1 frames" "$work/dropped.info" || fail "fminfo does not show the dropped frame"
grep -q "frame_0003.obj at 0.150 s" "$work/dropped.info" || fail "fminfo does not name the dropped frame"
"$tools/fmenc" "$work/cap" -o "$work/geometry.fmv" --grid 33 --no-texture --quiet || fail "--no-texture"
mv "$work/hidden.jpg" "$work/cap/frame_0003.jpg"
expect_error "unwritable output" "missing" "$tools/fmenc" "$work/cap" -o "$work/missing/b.fmv" --grid 33 --texture 64 --quiet
expect_error "bad option" "--keyframes" "$tools/fmenc" "$work/cap" -o "$work/c.fmv" --keyframes 150%
# Two reparametrisations asked for at once: one would be dropped silently.
expect_error "radial and density equalising" "are two reparametrisations of the disk" "$tools/fmenc" "$work/cap" -o "$work/c.fmv" --radial-equalising 1 --density-equalising 0.5
[[ ! -e "$work/c.fmv" ]] || fail "a refused encode wrote c.fmv"
# fmbench reads a fraction as fmenc does (one parser): 2 is not a keyframe budget there either.
expect_error "fmbench's keyframe budget" "--keyframes '2' is not a fraction in (0, 1]" "$tools/fmbench" temporal synth --keyframes 2 --quiet
expect_error "plain folder without fps" "--fps" "$tools/fmenc" "$work/seq" -o "$work/c.fmv"
expect_error "density-equalising strength" "density-equalising strength must be" "$tools/fmenc" "$work/cap" -o "$work/c.fmv" --density-equalising 2
# The density-equalising reparametrisation is the encoder's business: the file decodes as any other.
"$tools/fmenc" "$work/cap" -o "$work/dem.fmv" --grid 33 --no-texture --density-equalising 0.5 --quiet || fail "--density-equalising 0.5"
"$tools/fmdec" "$work/dem.fmv" --t 0.17 -o "$work/dem.obj" --quiet || fail "fmdec of a density-equalised file"
expect_error "keyframe fit" "--keyframe-fit" "$tools/fmenc" "$work/cap" -o "$work/c.fmv" --keyframe-fit maybe
expect_error "texture quality word" "--quality 'best' is neither auto nor a whole number from 0 to 101" "$tools/fmenc" "$work/cap" -o "$work/c.fmv" --quality best
expect_error "texture quality range" "--quality '102' is neither auto nor a whole number from 0 to 101" "$tools/fmenc" "$work/cap" -o "$work/c.fmv" --quality 102
# A count read in full: std::stoi alone took "65x" as 65 and "1e3" as 1.
expect_error "grid with a suffix" "--grid '65x' is neither auto nor a whole number from 5 to 4097" "$tools/fmenc" "$work/cap" -o "$work/c.fmv" --grid 65x
expect_error "grid in exponent form" "--grid '1e3' is neither auto" "$tools/fmenc" "$work/cap" -o "$work/c.fmv" --grid 1e3
expect_error "grid with a sign" "--grid '+65' is neither auto" "$tools/fmenc" "$work/cap" -o "$work/c.fmv" --grid +65
expect_error "grid after a blank" "--grid ' 65' is neither auto" "$tools/fmenc" "$work/cap" -o "$work/c.fmv" --grid " 65"
expect_error "texture with a unit" "--texture '64px' is neither auto nor a whole number from 16 to 16383" "$tools/fmenc" "$work/cap" -o "$work/c.fmv" --texture 64px
"$tools/fmenc" "$work/cap" -o "$work/own.fmv" --grid 33 --no-texture --keyframe-fit off --quiet || fail "--keyframe-fit off"
expect_error "inter dead zone" "--inter-dead-zone '1.5' is neither auto nor a number in" "$tools/fmenc" "$work/cap" -o "$work/c.fmv" --inter-dead-zone 1.5
expect_error "inter dead zone word" "--inter-dead-zone 'wide' is neither auto" "$tools/fmenc" "$work/cap" -o "$work/c.fmv" --inter-dead-zone wide
"$tools/fmenc" "$work/cap" -o "$work/zone.fmv" --grid 33 --no-texture --inter-dead-zone 0.6 --quiet || fail "--inter-dead-zone 0.6"
"$tools/fminfo" "$work/zone.fmv" | grep -q "\"inter_dead_zone\":0.6,\"inter_dead_zone_chosen\":0.6" || fail "--inter-dead-zone not in the settings"
"$tools/fminfo" "$work/own.fmv" | grep -q '"inter_dead_zone":"auto","inter_dead_zone_chosen":0\.[56]' || fail "--inter-dead-zone auto and its choice not in the settings"
expect_error "intra period" "--intra-period '0' is neither auto nor a whole number" "$tools/fmenc" "$work/cap" -o "$work/c.fmv" --intra-period 0
"$tools/fminfo" "$work/zone.fmv" | grep -q '"intra_period":"auto","intra_period_chosen":' || fail "--intra-period auto and its choice not in the settings"
# One coding (format 2.0): the older ones' option is gone, and fminfo shows the pose steps of the index.
expect_error "retired option" "--field-residuals" "$tools/fmenc" "$work/cap" -o "$work/c.fmv" --field-residuals zstd
"$tools/fminfo" "$work/zone.fmv" | grep -q "predicted and range-coded in groups of" || fail "fminfo does not describe the keyframe coding"
"$tools/fminfo" "$work/zone.fmv" | grep -q "^pose  *in the index: rotation vector in steps of 1e-05 rad, translation in steps of" || fail "fminfo shows no pose steps"
[[ ! -e "$work/c.fmv" ]] || fail "a refused encode wrote c.fmv"

# A depth camera's capture: colour per vertex, no image. It encodes with a texture and decodes with it.
"$tools/fmsynth" -o "$work/vc" --frames 6 --fps 20 --vertices 2000 --noise 0 --vertex-colour --quiet || fail "fmsynth --vertex-colour"
[[ -s "$work/vc/frame_0000.ply" && ! -e "$work/vc/frame_0000.jpg" ]] || fail "fmsynth --vertex-colour wrote no PLY frame, or an image"
grep -q "property uchar red" "$work/vc/frame_0000.ply" || fail "fmsynth --vertex-colour wrote no vertex colour"
"$tools/fminfo" "$work/vc" | grep -q "^texture  *colour per vertex" || fail "fminfo does not say the capture is coloured per vertex"
"$tools/fmenc" "$work/vc" -o "$work/vc.fmv" --grid 33 --keyframes 40% --quiet || fail "fmenc of a vertex-coloured capture"
"$tools/fminfo" "$work/vc.fmv" | grep -q "^texture  *128x128 AVIF image sequence per group" || fail "a vertex-coloured capture has no 128² texture (2000 vertices)"
"$tools/fmdec" "$work/vc.fmv" --t 0.1 -o "$work/vc.obj" --quiet || fail "fmdec of a vertex-coloured capture"
[[ -s "$work/vc.png" ]] || fail "the decoded vertex-coloured frame has no texture"

# A head-and-shoulders scan (hair, a shoulder) and the same scan with a plain dome where the face was
# (spec/method.md §7.14): --landmarks auto finds the face in the first; the second shows no face to
# the geometry or the texture and is refused by name, with no file written.
"$tools/fmsynth" -o "$work/hs" --surround --frames 2 --vertices 4000 --texture-size 64 --quiet || fail "fmsynth --surround"
"$tools/fmenc" "$work/hs" -o "$work/hs.fmv" --landmarks auto --grid 33 --no-texture >"$work/hs.txt" 2>&1 || fail "fmenc --landmarks auto on a head-and-shoulders scan: $(tail -3 "$work/hs.txt")"
grep -q "face region\|texture" "$work/hs.txt" || fail "fmenc's summary does not say how the face was found"
"$tools/fmsynth" -o "$work/dome" --surround --no-face --frames 2 --vertices 4000 --texture-size 64 --quiet || fail "fmsynth --surround --no-face"
[[ ! -e "$work/dome/landmarks.csv" ]] || fail "fmsynth --no-face wrote landmarks"
expect_error "a scan with no face" "no face found: neither the geometry nor the texture shows a face" \
  "$tools/fmenc" "$work/dome" -o "$work/dome.fmv" --landmarks auto --grid 33 --no-texture --quiet
grep -q "frame_0000.obj" "$work/err" || fail "the refusal does not name the frame: $(cat "$work/err")"
grep -q "face confidence" "$work/err" || fail "the refusal does not give the confidence: $(cat "$work/err")"
[[ ! -e "$work/dome.fmv" ]] || fail "a refused encode wrote dome.fmv"
expect_error "--no-face alone" "--no-face needs --surround" "$tools/fmsynth" -o "$work/nf" --no-face --frames 1 --quiet

# An interrupted encode (killed mid-way) leaves the earlier file as it was and no temporary behind.
# (Other settings than a.fmv's, so a finished encode would change it.)
"$tools/fmenc" "$work/cap" -o "$work/a.fmv" --grid 65 --texture 32 --quiet &
encoder=$!
sleep 0.3
kill -INT "$encoder" 2>/dev/null
if wait "$encoder" 2>/dev/null; then
  echo "note: the encode finished before the interrupt; interruption not exercised" >&2
  cp "$work/before.fmv" "$work/a.fmv"
fi
cmp -s "$work/a.fmv" "$work/before.fmv" || fail "an interrupted encode changed the earlier file"
[[ $(ls "$work" | grep -c '\.tmp') -eq 0 ]] || fail "an interrupted encode left a temporary file"

# The choice by bytes at equal error (spec/method.md §7.14) keeping a coarser N than --grid auto's
# terms chose: the summary names the N those terms chose as "the smallest within" the target and the
# N stored as coarser, not the stored one as the smallest (fmsynth's blinking face at seed 4: 49, 33).
"$tools/fmsynth" -o "$work/blink" --frames 24 --expression blink --vertices 3000 --remesh --seed 4 --texture-size 64 --quiet || fail "fmsynth blink"
"$tools/fmenc" "$work/blink" -o "$work/blink.fmv" --no-texture --threads 2 > "$work/blink.txt" 2>&1 || fail "fmenc blink: $(tail -1 "$work/blink.txt")"
planned=$(grep -o ')^2 the lowest[^:]*: hl+t N = [0-9]*' "$work/blink.txt" | grep -o '[0-9]*$')
kept=$(grep -o 'N = [0-9]*\( field step x[0-9.]*\)\? [0-9]* B at [0-9.]* / [0-9.]*% (kept)' "$work/blink.txt" | grep -o '^N = [0-9]*' | grep -o '[0-9]*$')
[[ -n "$planned" && -n "$kept" ]] || fail "fmenc's summary shows no choice by bytes at equal error"
[[ "$kept" != "$planned" ]] || echo "note: the blinking face kept N = $planned; the coarser N's line not exercised" >&2
grep -q "grid auto: N = $planned, the smallest within" "$work/blink.txt" || fail "the summary's N 'the smallest within' is not --grid auto's ($planned)"
if [[ "$kept" != "$planned" ]]; then
  grep -q "grid auto: N = $kept stored, coarser" "$work/blink.txt" || fail "the summary does not say N = $kept was kept coarser than $planned"
fi

if ((failures > 0)); then
  echo "$failures failures" >&2
  exit 1
fi
echo "command-line contract: all checks passed"
