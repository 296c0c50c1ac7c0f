#!/usr/bin/env python3
"""A whole-head capture from ICT-FaceKit's model (../shared/data/ict-facekit), for issue 47 part 2:
the face area (its eye and mouth holes open) joined to the back of the head down to the neck rim,
or with --pieces the model's separate eyeballs, teeth, gums and lashes too (extra surfaces the
encoder drops with --largest-component). Frames blend the neutral with jawOpen, eyeBlink and
mouthSmile; landmarks are ICT's 68 Multi-PIE points and rim_0..5 on the neck rim. Standard library
only; it reads the data where it lies and writes a capture folder (nothing is copied into the project).

With --face-only, the face area alone (the same frames cropped to the face, rim_0..5 on its outer
rim): the cropped face a whole head's error is compared with (spec/method.md §7.11).

usage: ict_whole_head.py OUT_DIR [--frames 6] [--pieces | --face-only] [--data ../shared/data]
"""
import argparse, collections, json, lzma, math, os

MPIE68 = [1225, 1888, 1052, 367, 1719, 1722, 2199, 1447, 966, 3661, 4390, 3927, 3924, 2608, 3272, 4088, 3443, 268,
          493, 1914, 2044, 1401, 3615, 4240, 4114, 2734, 2509, 978, 4527, 4942, 4857, 1140, 2075, 1147, 4269, 3360,
          1507, 1542, 1537, 1528, 1518, 1511, 3742, 3751, 3756, 3721, 3725, 3732, 5708, 5695, 2081, 0, 4275, 6200,
          6213, 6346, 6461, 5518, 5957, 5841, 5702, 5711, 5533, 6216, 6207, 6470, 5517, 5966]
NAMED = {30: 'nose_tip', 27: 'nose_bridge', 8: 'chin', 36: 'right_eye_outer_corner', 39: 'right_eye_inner_corner',
         42: 'left_eye_inner_corner', 45: 'left_eye_outer_corner', 48: 'mouth_corner_right', 54: 'mouth_corner_left',
         51: 'upper_lip_top_midline', 57: 'lower_lip_bottom_midline'}
SHAPES = ['jawOpen', 'eyeBlink_L', 'eyeBlink_R', 'mouthSmile_L', 'mouthSmile_R']
FACE_AREA_POLYGONS = 9230  # polygons 0..9229: the face area, whose eye and mouth holes stay open


def read_vertices(path):
    with lzma.open(path, 'rt') as f:
        return [[float(x) for x in line.split()[1:4]] for line in f if line.startswith('v ')]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('out')
    ap.add_argument('--frames', type=int, default=6)
    ap.add_argument('--pieces', action='store_true', help='also the eyeballs, teeth, gums and lashes, separate surfaces')
    ap.add_argument('--face-only', action='store_true', help='the face area alone: the whole head cropped to its face')
    ap.add_argument('--data', default=os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', '..', 'shared', 'data'))
    a = ap.parse_args()
    model = os.path.join(a.data, 'ict-facekit', 'originals', 'FaceXModel')
    polygons, back, material, index = [], [], None, -1
    with lzma.open(os.path.join(model, 'generic_neutral_mesh.obj.xz'), 'rt') as f:
        for line in f:
            if line.startswith('usemtl'):
                material = line.split()[1]
            elif line.startswith('f '):
                index += 1
                poly = [int(t.split('/')[0]) - 1 for t in line.split()[1:]]
                if index < FACE_AREA_POLYGONS:
                    polygons.append(poly)
                elif material == 'M_BackHead':
                    back.append(poly)
                elif a.pieces:
                    polygons.append(poly)
    neutral = read_vertices(os.path.join(model, 'generic_neutral_mesh.obj.xz'))
    # M_BackHead is the back of the head and, apart, the sockets behind the eyes and the mouth: the
    # part that reaches the neck (the lowest vertex) is kept, so the eyes and mouth stay holes.
    parent = list(range(len(back)))

    def find(x):
        while parent[x] != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x
    by_edge = collections.defaultdict(list)
    for i, poly in enumerate(back):
        for k in range(len(poly)):
            u, v = poly[k], poly[(k + 1) % len(poly)]
            by_edge[(min(u, v), max(u, v))].append(i)
    for faces in by_edge.values():
        for j in faces[1:]:
            parent[find(j)] = find(faces[0])
    neck = find(min(range(len(back)), key=lambda i: min(neutral[v][1] for v in back[i])))
    if not a.face_only:
        polygons += [poly for i, poly in enumerate(back) if find(i) == neck]
    triangles = [(p[0], p[k], p[k + 1]) for p in polygons for k in range(1, len(p) - 1)]
    used = sorted({v for t in triangles for v in t})
    number = {v: i + 1 for i, v in enumerate(used)}
    # The neck rim (the face area's outer rim with --face-only): the boundary loop through the lowest
    # vertex; rim_0..5 evenly along it.
    directed = collections.Counter((t[k], t[(k + 1) % 3]) for t in triangles for k in range(3))
    following = {u: v for (u, v) in directed if (v, u) not in directed}
    start = min(following, key=lambda v: neutral[v][1])
    rim, v = [start], following[start]
    while v != start:
        rim.append(v)
        v = following[v]
    landmarks = {NAMED.get(i, 'mpie_%02d' % i): v for i, v in enumerate(MPIE68)}
    for j in range(6):
        landmarks['rim_%d' % j] = rim[j * len(rim) // 6]
    shapes = {name: read_vertices(os.path.join(model, name + '.obj.xz')) for name in SHAPES}
    os.makedirs(a.out, exist_ok=True)
    rows, names = [], []
    for k in range(a.frames):
        t = k / max(a.frames - 1, 1)
        weights = {'jawOpen': 0.6 * math.sin(math.pi * t), 'eyeBlink_L': float(k == a.frames // 2),
                   'eyeBlink_R': float(k == a.frames // 2), 'mouthSmile_L': 0.5 * t, 'mouthSmile_R': 0.5 * t}
        V = {v: list(neutral[v]) for v in used}
        for name, w in weights.items():
            if w == 0:
                continue
            shape = shapes[name]
            for v in used:
                for c in range(3):
                    V[v][c] += w * (shape[v][c] - neutral[v][c])
        name = 'frame_%04d.obj' % k
        names.append(name)
        with open(os.path.join(a.out, name), 'w') as o:
            for v in used:
                o.write('v %.6f %.6f %.6f\n' % tuple(V[v]))
            for t3 in triangles:
                o.write('f %d %d %d\n' % tuple(number[v] for v in t3))
        for lname, v in landmarks.items():
            rows.append('%d,%s,%.6g,%.6g,%.6g' % (k, lname, *V[v]))
    with open(os.path.join(a.out, 'landmarks.csv'), 'w') as f:
        f.write('frame,name,x,y,z\n' + '\n'.join(rows) + '\n')
    what = 'face area' if a.face_only else 'whole head to the neck'
    manifest = {'description': 'ICT-FaceKit %s%s, eyes and mouth open; %d frames'
                               % (what, ' with its eyes, teeth, gums and lashes' if a.pieces else '', len(names)),
                'fps': 10, 'units': 'cm', 'frames': [{'mesh': n, 'time': k / 10} for k, n in enumerate(names)],
                'landmarks_csv': 'landmarks.csv'}
    with open(os.path.join(a.out, 'capture.json'), 'w') as f:
        json.dump(manifest, f, indent=1)
    print('%s: %d frames, %d vertices, %d triangles, rim of %d vertices' % (a.out, len(names), len(used), len(triangles), len(rim)))


if __name__ == '__main__':
    main()
