"""Blender.ImportPlaysAndRenders: the add-on as shipped (its zip), in `blender -b --factory-startup`.

    blender -b --factory-startup --python-exit-code 1 --python test_addon.py -- \
        ADDON.zip PACKAGE_DIR FMDEC DATA_DIR WORK_DIR

Checked against fmdec (the C++ decoder behind the command line), never against the add-on's own
module calls:
1. errors are reports: the module missing, a file that is not .fmv, a truncated file (the operator
   is CANCELLED with the library's message; no object is made);
2. golden_v2_1.fmv imported to follow the scene's time: fps and frame range from the file; at three
   frames stepped out of order, the evaluated mesh's vertices equal `fmdec --t T -o x.obj`'s within
   1e-5 of the face's diagonal (the decoder's bits follow its history: spec/python.md §2), and the
   texture image equals fmdec's texture within one level of 255;
3. one frame rendered with Cycles on the CPU (160², 4 samples), the camera set as fmdec's preview
   sets its own (orthographic, yaw 20°, the box fitted with 5% margin): the face covers more than
   10% of it, its silhouette (alpha > 0.5) against `fmdec --preview`'s (not white) has IoU >= 0.98,
   and its colours are the texture's (chromaticity within 0.03 of the preview's on average);
4. File > Export: the followed golden face encoded again (facemorph.encode) and decoded by fmdec
   is the same surface within the codec's error, in the same place, with the same colours;
5. golden_v2_6.fmv (format 2.6: positions under the levels predictor, in a KGLV chunk) followed at
   three frames as in 2., its texture fmdec's;
6. holes.fmv (eyes and mouth cut per frame, counts changing between frames): followed, each frame's
   vertices and triangles equal fmdec's, and its export is refused by a report; baked to shape keys, each baked frame shows fmdec's
   --keep-holes-filled frame.
"""

import math
import os
import subprocess
import sys
import time

import bpy

try:
    import numpy as np
except ImportError:
    print("SKIP: Blender's Python cannot import numpy (Debian's blender depends on python3-numpy)")
    sys.exit(77)
from mathutils import Matrix, Vector

ADDON_ZIP, PACKAGE_DIR, FMDEC, DATA_DIR, WORK = sys.argv[sys.argv.index("--") + 1:]
GOLDEN = os.path.join(DATA_DIR, "golden_v2_1.fmv")
GOLDEN_2_6 = os.path.join(DATA_DIR, "golden_v2_6.fmv")  # positions under the levels predictor (KGLV)
HOLES = os.path.join(os.path.dirname(os.path.abspath(__file__)), "data", "holes.fmv")
POSITION_TOLERANCE = 1e-5  # of the bounding-box diagonal
IOU_BOUND = 0.98
CHROMA_BOUND = 0.03
PREVIEW_SIZE = 160
EXPORT_MEAN_BOUND, EXPORT_MAX_BOUND = 0.01, 0.03  # re-encoded: measured 0.002-0.005 and 0.004-0.014
EXPORT_COLOUR_BOUND = 6.0
failures = []
started = time.monotonic()


def check(condition, what):
    print(("ok   " if condition else "FAIL ") + what, flush=True)
    if not condition:
        failures.append(what)


def fmdec(*args):
    subprocess.run([FMDEC, *map(str, args)], check=True, stdout=subprocess.DEVNULL)


def read_obj(path):
    """(positions, faces) of fmdec's OBJ."""
    vertices, faces = [], []
    with open(path) as handle:
        for line in handle:
            if line.startswith("v "):
                vertices.append([float(x) for x in line.split()[1:4]])
            elif line.startswith("f "):
                faces.append([int(token.split("/")[0]) - 1 for token in line.split()[1:4]])
    return np.array(vertices), np.array(faces, dtype=np.int64)


def vertex_colours(path):
    """Each vertex's colour (0..255) in fmdec's OBJ: its texture (the PNG beside it) at its UV."""
    uvs, corner_uv = [], {}
    with open(path) as handle:
        for line in handle:
            if line.startswith("vt "):
                uvs.append([float(x) for x in line.split()[1:3]])
            elif line.startswith("f "):
                for token in line.split()[1:4]:
                    vertex, uv = token.split("/")[:2]
                    corner_uv[int(vertex) - 1] = int(uv) - 1
    uv = np.array(uvs)[[corner_uv[v] for v in range(len(corner_uv))]]
    texture = image_array(path.replace(".obj", ".png"))[..., :3] * 255  # bottom row first: v up
    height, width = texture.shape[:2]
    rows = np.clip((uv[:, 1] * height).astype(int), 0, height - 1)
    columns = np.clip((uv[:, 0] * width).astype(int), 0, width - 1)
    return texture[rows, columns]


def image_array(path):
    """RGBA floats, bottom row first (Blender's order), of a PNG."""
    image = bpy.data.images.load(path)
    pixels = np.empty(len(image.pixels), dtype=np.float32)
    image.pixels.foreach_get(pixels)
    shape = (image.size[1], image.size[0], 4)
    bpy.data.images.remove(image)
    return pixels.reshape(shape)


def evaluated_mesh(obj):
    """Vertices and triangles of obj as the depsgraph evaluates it (what renders)."""
    evaluated = obj.evaluated_get(bpy.context.evaluated_depsgraph_get())
    mesh = evaluated.to_mesh()
    positions = np.empty(3 * len(mesh.vertices), dtype=np.float32)
    mesh.vertices.foreach_get("co", positions)
    corners = np.empty(len(mesh.loops), dtype=np.int32)
    mesh.loops.foreach_get("vertex_index", corners)
    evaluated.to_mesh_clear()
    return positions.reshape(-1, 3).astype(np.float64), corners.reshape(-1, 3).astype(np.int64)


def same_triangles(a, b):
    """The same triangles, each up to a rotation of its corners."""
    def canonical(faces):
        rolled = np.array([np.roll(faces, -k, axis=1) for k in range(3)])  # (3, m, 3)
        first = np.argmin(faces, axis=1)
        return rolled[first, np.arange(len(faces))]
    return a.shape == b.shape and np.array_equal(canonical(a), canonical(b))


def import_fmv(path, **options):
    before = set(bpy.data.objects)
    result = bpy.ops.import_scene.facemorph(filepath=path, **options)
    made = [obj for obj in bpy.data.objects if obj not in before]
    return result, made


def expect_report(path, words, label):
    before = len(bpy.data.objects)
    try:
        bpy.ops.import_scene.facemorph(filepath=path)
        check(False, f"{label}: the import should fail with a report")
    except RuntimeError as report:  # an operator's ERROR report, as Python sees it
        text = str(report)
        check(all(word in text for word in words) and "Traceback" not in text,
              f"{label}: reported {text.strip()!r} (expects {words})")
    check(len(bpy.data.objects) == before, f"{label}: no object made")


def enable_addon():
    bpy.ops.preferences.addon_install(filepath=ADDON_ZIP, overwrite=True)
    bpy.ops.preferences.addon_enable(module="facemorph_blender")
    return bpy.context.preferences.addons["facemorph_blender"].preferences


def check_errors(preferences):
    # The module missing: an empty preference folder, nothing importable (None in sys.modules
    # makes `import facemorph` fail as an absent module does).
    preferences.module_folder = os.path.join(WORK, "empty")
    os.makedirs(preferences.module_folder, exist_ok=True)
    sys.modules["facemorph"] = None
    expect_report(GOLDEN, ["facemorph Python module cannot be imported", "Module folder"], "module missing")
    del sys.modules["facemorph"]
    preferences.module_folder = PACKAGE_DIR

    not_fmv = os.path.join(WORK, "not_a_face.fmv")
    with open(not_fmv, "wb") as handle:
        handle.write(b"\x89PNG\r\n\x1a\n" + bytes(200))
    expect_report(not_fmv, ["CorruptError", "not_a_face.fmv"], "a PNG named .fmv")
    truncated = os.path.join(WORK, "truncated.fmv")
    with open(GOLDEN, "rb") as source, open(truncated, "wb") as handle:
        handle.write(source.read()[:300])
    expect_report(truncated, ["truncated.fmv"], "a truncated file")


def check_follows_time(obj, path, frames, fps, label):
    """At each frame (in this order) the evaluated mesh is fmdec's frame; returns the diagonal."""
    scene = bpy.context.scene
    shapes = []
    for frame in frames:
        t = frame / fps
        started_frame = time.perf_counter()
        scene.frame_set(frame)
        elapsed = time.perf_counter() - started_frame
        reference = os.path.join(WORK, f"{label}_{frame}.obj")
        fmdec(path, "--t", repr(t), "-o", reference)
        want_positions, want_faces = read_obj(reference)
        got_positions, got_faces = evaluated_mesh(obj)
        diagonal = float(np.linalg.norm(want_positions.max(0) - want_positions.min(0)))
        if got_positions.shape != want_positions.shape:
            check(False, f"{label} frame {frame}: {len(got_positions)} vertices, fmdec {len(want_positions)}")
            continue
        error = float(np.abs(got_positions - want_positions).max()) / diagonal
        check(error <= POSITION_TOLERANCE,
              f"{label} frame {frame} (t = {t:.4f} s, {elapsed * 1000:.1f} ms): {len(got_positions)} vertices, "
              f"largest difference from fmdec {error:.2e} of the diagonal (bound {POSITION_TOLERANCE:g})")
        check(same_triangles(got_faces, want_faces), f"{label} frame {frame}: the triangles are fmdec's ({len(want_faces)})")
        shapes.append(got_positions)
    # The frames differ (else equality above would say nothing about following time).
    if len(frames) > 1 and len(shapes) == len(frames) and all(s.shape == shapes[0].shape for s in shapes):
        moved = max(float(np.abs(a - b).max()) for a, b in zip(shapes, shapes[1:])) / diagonal
        check(moved > 100 * POSITION_TOLERANCE, f"{label}: the frames differ by up to {moved:.2e} of the diagonal")
    return diagonal


def check_texture(obj, frame, label):
    reference = os.path.join(WORK, f"{label}_{frame}.png")  # fmdec's texture beside its OBJ
    want = image_array(reference)[..., :3]
    image = obj.facemorph.image
    got = np.empty(len(image.pixels), dtype=np.float32)
    image.pixels.foreach_get(got)
    got = got.reshape(image.size[1], image.size[0], 4)[..., :3]
    difference = float(np.abs(got - want).max()) * 255 if got.shape == want.shape else float("inf")
    check(difference <= 1.0, f"{label} frame {frame}: texture {image.size[0]}² equals fmdec's within {difference:.2f} of 255")


def preview_rotation(yaw_degrees):
    """fmdec --preview's rotation (meshkit render: pitch about x after yaw about y; pitch 0)."""
    yaw = math.radians(yaw_degrees)
    return Matrix(((math.cos(yaw), 0, math.sin(yaw)), (0, 1, 0), (-math.sin(yaw), 0, math.cos(yaw))))


def set_preview_camera(scene, obj, positions, yaw_degrees=20.0, margin=0.05):
    """An orthographic camera that frames fmdec's frame (positions, the capture's coordinates) as
    fmdec's preview does, placed through obj's transform: the mesh turned by the yaw, seen down -z,
    the turned box's larger side filling (1 - 2 margin) of the picture. Fitted to fmdec's frame,
    not to Blender's mesh, so a mesh that is not that frame shows in the silhouette."""
    rotation = preview_rotation(yaw_degrees)
    turned = positions @ np.array(rotation).T
    low, high = turned.min(0), turned.max(0)
    extent = max(high[0] - low[0], high[1] - low[1])
    centre = rotation.transposed() @ Vector((0.5 * (low[0] + high[0]), 0.5 * (low[1] + high[1]), high[2] + extent))
    world = obj.matrix_world
    camera = bpy.data.objects.new("preview camera", bpy.data.cameras.new("preview camera"))
    camera.data.type = "ORTHO"
    camera.data.ortho_scale = extent * world.to_scale()[0] / (1 - 2 * margin)
    camera.data.clip_end = 10 * extent * world.to_scale()[0] + 1
    orientation = world.to_3x3().normalized() @ rotation.transposed()
    camera.matrix_world = Matrix.Translation(world @ centre) @ orientation.to_4x4()
    scene.collection.objects.link(camera)
    scene.camera = camera


def render(scene, path):
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = 4
    scene.cycles.use_denoising = False  # Debian's Blender has no OpenImageDenoise
    scene.render.resolution_x = scene.render.resolution_y = PREVIEW_SIZE
    scene.render.resolution_percentage = 100
    scene.render.film_transparent = True  # alpha is the silhouette
    scene.view_settings.view_transform = "Standard"  # colours as the texture's sRGB, not Filmic's curve
    world = bpy.data.worlds.new("even light")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (1, 1, 1, 1)
    scene.world = world
    scene.render.image_settings.file_format = "PNG"
    scene.render.image_settings.color_mode = "RGBA"
    scene.render.filepath = path
    bpy.ops.render.render(write_still=True)


def check_render(obj, frame, fps):
    scene = bpy.context.scene
    scene.frame_set(frame)
    reference = os.path.join(WORK, f"render_{frame}.obj")
    fmdec(GOLDEN, "--t", repr(frame / fps), "-o", reference)
    set_preview_camera(scene, obj, read_obj(reference)[0])
    picture = os.path.join(WORK, "render.png")
    started_render = time.perf_counter()
    render(scene, picture)
    print(f"     render {PREVIEW_SIZE}² at 4 samples: {time.perf_counter() - started_render:.2f} s")
    preview_path = os.path.join(WORK, "preview.png")
    fmdec(GOLDEN, "--t", repr(frame / fps), "--preview", preview_path, "--preview-size", PREVIEW_SIZE)
    rendered, preview = image_array(picture), image_array(preview_path)
    face = rendered[..., 3] > 0.5
    preview_face = np.any(preview[..., :3] < 254.5 / 255, axis=2)  # the preview's background is white
    coverage = face.mean()
    check(coverage > 0.10, f"render: the face covers {100 * coverage:.1f}% of the picture (> 10%)")
    iou = float((face & preview_face).sum() / max(1, (face | preview_face).sum()))
    check(iou >= IOU_BOUND, f"render: silhouette IoU with fmdec --preview {iou:.4f} (bound {IOU_BOUND}; "
                            f"{int(face.sum())} and {int(preview_face.sum())} pixels)")
    both = face & preview_face
    def chroma(rgb):
        return rgb / np.maximum(rgb.sum(axis=-1, keepdims=True), 1e-6)
    rendered_chroma, preview_chroma = chroma(rendered[both][:, :3]), chroma(preview[both][:, :3])
    difference = float(np.abs(rendered_chroma - preview_chroma).sum(axis=1).mean())
    grey = float(np.abs(preview_chroma - 1 / 3).sum(axis=1).mean())  # what an untextured face would score
    check(difference <= CHROMA_BOUND and grey > 2 * CHROMA_BOUND,
          f"render: chromaticity within {difference:.4f} of the preview's on average (bound {CHROMA_BOUND}; a grey face: {grey:.4f})")
    return picture


def check_export(obj, fps):
    """The followed golden face exported through facemorph.encode and decoded again by fmdec: the
    same surface within the codec's error (nearest vertices, of the diagonal), in the same place
    (the importer's transform undone), with the same texture colours."""
    exported = os.path.join(WORK, "exported.fmv")
    started_export = time.perf_counter()
    result = bpy.ops.export_scene.facemorph(filepath=exported)
    check(result == {"FINISHED"} and os.path.getsize(exported) > 0,
          f"exported to .fmv in {time.perf_counter() - started_export:.2f} s ({os.path.getsize(exported)} bytes)")
    for frame in (0, 5, 11):
        original = os.path.join(WORK, f"golden_{frame}.obj")  # fmdec's frames of golden_v2_1
        again = os.path.join(WORK, f"exported_{frame}.obj")
        fmdec(exported, "--t", repr(frame / fps), "-o", again)
        want, got = read_obj(original)[0], read_obj(again)[0]
        diagonal = float(np.linalg.norm(want.max(0) - want.min(0)))
        distance = np.sqrt(((got[:, None, :] - want[None, :, :]) ** 2).sum(-1))
        there, back = distance.min(axis=1) / diagonal, distance.min(axis=0) / diagonal
        check(max(there.mean(), back.mean()) <= EXPORT_MEAN_BOUND and max(there.max(), back.max()) <= EXPORT_MAX_BOUND,
              f"export frame {frame}: nearest vertices {max(there.mean(), back.mean()):.4f} of the diagonal on average, "
              f"{max(there.max(), back.max()):.4f} at most (bounds {EXPORT_MEAN_BOUND}, {EXPORT_MAX_BOUND})")
        # Colours where the surfaces meet: each vertex's texel against its nearest original vertex's.
        nearest = distance.argmin(axis=1)
        difference = float(np.abs(vertex_colours(again) - vertex_colours(original)[nearest]).mean())
        check(difference <= EXPORT_COLOUR_BOUND, f"export frame {frame}: a vertex's colour within {difference:.2f} of 255 of its "
                                                 f"nearest original's on average (bound {EXPORT_COLOUR_BOUND})")


def main():
    os.makedirs(WORK, exist_ok=True)
    preferences = enable_addon()
    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj)
    check_errors(preferences)

    result, made = import_fmv(GOLDEN)
    check(result == {"FINISHED"} and len(made) == 1, f"golden_v2_1.fmv imported: {result}, {len(made)} object")
    obj = made[0]
    scene = bpy.context.scene
    fps = scene.render.fps / scene.render.fps_base
    check((fps, scene.frame_start, scene.frame_end) == (30.0, 0, 11),
          f"scene from the file: {fps} fps, frames {scene.frame_start}..{scene.frame_end} (30 fps, 0..11)")
    # Blender's front view looks along +y with z up: the capture's up (+y) is world +z, and the
    # side the face looks to (+z) is world -y.
    turn = obj.matrix_world.to_3x3().normalized()
    up, facing = turn @ Vector((0, 1, 0)), turn @ Vector((0, 0, 1))
    check((up - Vector((0, 0, 1))).length < 1e-6 and (facing - Vector((0, -1, 0))).length < 1e-6,
          f"the face is upright in Blender: up {tuple(round(x, 3) for x in up)}, facing {tuple(round(x, 3) for x in facing)}")
    check_follows_time(obj, GOLDEN, [5, 11, 0], fps, "golden")
    for frame in (5, 11, 0):
        scene.frame_set(frame)
        check_texture(obj, frame, "golden")
    picture = check_render(obj, 6, fps)
    print(f"     picture: {picture}")
    check_export(obj, fps)
    scene.frame_set(11)
    obj_image = obj.facemorph.image
    bpy.data.objects.remove(obj)
    # Imported again at the frame the deleted object showed: the new object takes its name, and
    # must still show the frame (mesh and texture).
    result, made = import_fmv(GOLDEN)
    check(result == {"FINISHED"} and len(made) == 1 and made[0].name == "golden_v2_1", "golden_v2_1.fmv imported again")
    check_follows_time(made[0], GOLDEN, [11], fps, "golden_again")
    check_texture(made[0], 11, "golden_again")
    check(made[0].facemorph.image != obj_image, f"its own image ({made[0].facemorph.image.name}), not the deleted object's")
    bpy.data.objects.remove(made[0])

    # Format 2.6: a group whose positions the levels predictor codes (a KGLV chunk) plays as fmdec
    # decodes it, mesh and texture.
    result, made = import_fmv(GOLDEN_2_6)
    check(result == {"FINISHED"} and len(made) == 1, f"golden_v2_6.fmv (KGLV) imported: {result}, {len(made)} object")
    if made:
        check_follows_time(made[0], GOLDEN_2_6, [5, 11, 0], fps, "golden_v2_6")
        check_texture(made[0], 0, "golden_v2_6")
        bpy.data.objects.remove(made[0])

    result, made = import_fmv(HOLES)
    check(result == {"FINISHED"} and len(made) == 1, "holes.fmv imported to follow time")
    check_follows_time(made[0], HOLES, [0, 3, 7], fps, "holes")
    # Its topology changes between frames: the exporter refuses by a report, writing nothing.
    refused = os.path.join(WORK, "holes_exported.fmv")
    try:
        bpy.ops.export_scene.facemorph(filepath=refused)
        check(False, "exporting a mesh whose topology changes should fail with a report")
    except RuntimeError as report:
        check("topology changed" in str(report) and not os.path.exists(refused),
              f"export of holes.fmv refused: {str(report).strip()!r}, no file")
    bpy.data.objects.remove(made[0])

    result, made = import_fmv(HOLES, geometry="SHAPE_KEYS", texture="STILL")
    check(result == {"FINISHED"} and len(made) == 1, "holes.fmv baked to shape keys")
    obj = made[0]
    keys = obj.data.shape_keys
    check(keys is not None and len(keys.key_blocks) == 8, f"8 shape keys, one a frame ({len(keys.key_blocks) if keys else 0})")
    for frame in (3, 7, 0):
        scene.frame_set(frame)
        reference = os.path.join(WORK, f"filled_{frame}.obj")
        fmdec(HOLES, "--t", repr(frame / fps), "--keep-holes-filled", "-o", reference)
        want, _ = read_obj(reference)
        got, _ = evaluated_mesh(obj)
        diagonal = float(np.linalg.norm(want.max(0) - want.min(0)))
        error = float(np.abs(got - want).max()) / diagonal if got.shape == want.shape else float("inf")
        check(error <= POSITION_TOLERANCE, f"shape keys frame {frame}: fmdec --keep-holes-filled's within {error:.2e} of the diagonal")

    print(f"     {time.monotonic() - started:.1f} s in Blender's Python")
    if failures:
        raise SystemExit(f"{len(failures)} check(s) failed: " + "; ".join(failures))


main()
