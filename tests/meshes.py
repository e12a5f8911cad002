"""Small meshes built from numpy for the tests (no files, no Blender)."""

import numpy as np

import smoothffd


def icosphere(subdivisions=2):
    """Unit icosphere: (V, 3) positions on the sphere, (F, 3) triangles (20 * 4^s faces)."""
    t = (1 + 5 ** 0.5) / 2
    V = [[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t], [0, -1, -t],
         [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]]
    F = [[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4],
         [11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8],
         [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]]
    V = [np.array(v, float) / np.linalg.norm(v) for v in V]
    for _ in range(subdivisions):
        cache, out = {}, []

        def mid(a, b):
            key = (min(a, b), max(a, b))
            if key not in cache:
                m = V[a] + V[b]
                V.append(m / np.linalg.norm(m))
                cache[key] = len(V) - 1
            return cache[key]

        for a, b, c in F:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            out += [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
        F = out
    return np.array(V), np.array(F, dtype=np.int64)


def sphere_mesh(subdivisions=2):
    """Icosphere with the exact sphere normals as split normals."""
    V, F = icosphere(subdivisions)
    return smoothffd.Mesh(V, F, corner_normals=V[F.reshape(-1)])


def cube_mesh(size=1.0, sharp=True):
    """Cube [-size, size]^3 as 6 quads sharing 8 vertices. sharp=True: split normals (each
    face's own normal at its corners); sharp=False: smooth vertex normals."""
    s = size
    V = np.array([[x, y, z] for x in (-s, s) for y in (-s, s) for z in (-s, s)], float)
    quads = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]]
    cv = np.array(quads).reshape(-1)
    fo = np.arange(0, 25, 4)
    normals = None
    if sharp:
        fn = []
        for q in quads:
            a, b, c = V[q[0]], V[q[1]], V[q[2]]
            n = np.cross(b - a, c - a)
            fn += [n / np.linalg.norm(n)] * 4
        normals = np.array(fn)
    return smoothffd.Mesh(V, (cv, fo), corner_normals=normals)


def cube_face_normals(mesh):
    """Unit normal of each (planar) input face, (F, 3)."""
    out = []
    for f in range(mesh.face_count):
        idx = mesh.corner_vertices[mesh.face_offsets[f]:mesh.face_offsets[f + 1]]
        a, b, c = mesh.positions[idx[:3]]
        n = np.cross(b - a, c - a)
        out.append(n / np.linalg.norm(n))
    return np.array(out)


def edge_counts(triangles):
    """For each undirected edge of a triangle list, how many triangles use it."""
    T = np.asarray(triangles)
    e = np.sort(np.concatenate([T[:, [0, 1]], T[:, [1, 2]], T[:, [2, 0]]]), axis=1)
    _, counts = np.unique(e, axis=0, return_counts=True)
    return counts


def random_bspline_lattice(rng, box_min, box_max, shape, degree, amount):
    """Identity lattice with every control point moved by a uniform random offset."""
    lat = smoothffd.BSplineLattice.identity(box_min, box_max, shape=shape, degree=degree)
    cp = lat.control_points + rng.uniform(-amount, amount, lat.control_points.shape)
    return lat.with_control_points(cp)


def twist_lattice(lattice, degrees):
    """Rotate the control points about z by an angle growing linearly with z."""
    cp = lattice.control_points.copy()
    z = cp[..., 2]
    zn = (z - z.min()) / max(z.max() - z.min(), 1e-12)
    ang = np.radians(degrees) * (zn - 0.5)
    c, s = np.cos(ang), np.sin(ang)
    x, y = cp[..., 0].copy(), cp[..., 1].copy()
    cp[..., 0] = c * x - s * y
    cp[..., 1] = s * x + c * y
    return lattice.with_control_points(cp)


def grid_cube(n, size=1.0):
    """Cube [-size, size]^3, each face split into n x n quads, welded vertices, split face
    normals (sharp edges): the paper's error-test cube (sec. 6.3)."""
    index, V, cv, fo, cn = {}, [], [], [0], []

    def vid(p):
        key = tuple(np.round(p, 9))
        if key not in index:
            index[key] = len(V)
            V.append(p)
        return index[key]

    for axis in range(3):
        for sign in (-1.0, 1.0):
            nrm = np.zeros(3)
            nrm[axis] = sign
            u, w = np.zeros(3), np.zeros(3)
            u[(axis + 1) % 3], w[(axis + 2) % 3] = 1, 1
            if sign < 0:
                u, w = w, u
            for i in range(n):
                for j in range(n):
                    for di, dj in ((0, 0), (1, 0), (1, 1), (0, 1)):
                        a, b = -1 + 2 * (i + di) / n, -1 + 2 * (j + dj) / n
                        cv.append(vid(size * (nrm + a * u + b * w)))
                        cn.append(nrm)
                    fo.append(len(cv))
    return smoothffd.Mesh(np.array(V), (np.array(cv), np.array(fo)), corner_normals=np.array(cn))


def bulge_twist(lattice, bulge=0.25, twist_degrees=45):
    """The documented deformation family of the error tests: control points pushed outwards
    by (1 + bulge * exp(-|p|^2)), then twisted about z by `twist_degrees` over the height."""
    cp = lattice.control_points.copy()
    cp *= 1 + bulge * np.exp(-np.sum(cp ** 2, axis=-1, keepdims=True))
    return twist_lattice(lattice.with_control_points(cp), twist_degrees)


def uv_sphere(segments=32, rings=16):
    """Blender-style UV sphere with float32 coordinates: its meridian vertices sit about 4e-8
    off the x = 0 / y = 0 planes instead of on them, as Blender's do."""
    V = [[0, 0, 1]]
    for i in range(1, rings):
        th = np.float32(np.pi * i / rings)
        for j in range(segments):
            ph = np.float32(2 * np.pi * j / segments)
            V.append([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)])
    V.append([0, 0, -1])
    V = np.array(V, np.float32).astype(np.float64)
    F = [[0, 1 + j, 1 + (j + 1) % segments] for j in range(segments)]
    for i in range(rings - 2):
        for j in range(segments):
            a, b = 1 + i * segments + j, 1 + i * segments + (j + 1) % segments
            F += [[a, a + segments, b + segments], [a, b + segments, b]]
    last, base = len(V) - 1, 1 + (rings - 2) * segments
    F += [[base + j, last, base + (j + 1) % segments] for j in range(segments)]
    return V, np.array(F)


def read_glb(path):
    """The first mesh primitive of a binary glTF file (.glb) as a smoothffd.Mesh: its
    triangles as the file lists them (non-indexed primitives give one vertex per corner, as
    exporters write flat-shaded models: a triangle soup). Only what the tests' assets use:
    float32 VEC3 positions, optional unsigned indices, mode 4 (triangles)."""
    import json
    import struct
    with open(path, "rb") as f:
        data = f.read()
    magic, version, _length = struct.unpack_from("<4sII", data, 0)
    assert magic == b"glTF" and version == 2, (magic, version)
    json_len, json_type = struct.unpack_from("<I4s", data, 12)
    assert json_type == b"JSON"
    doc = json.loads(data[20:20 + json_len])
    bin_at = 20 + json_len + 8
    assert struct.unpack_from("<4s", data, bin_at - 4)[0] == b"BIN\0"

    def accessor(i):
        acc = doc["accessors"][i]
        view = doc["bufferViews"][acc["bufferView"]]
        dtype = {5126: np.float32, 5125: np.uint32, 5123: np.uint16, 5121: np.uint8}[acc["componentType"]]
        width = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}[acc["type"]]
        assert view.get("byteStride", 0) in (0, width * np.dtype(dtype).itemsize)
        at = bin_at + view.get("byteOffset", 0) + acc.get("byteOffset", 0)
        return np.frombuffer(data, dtype, acc["count"] * width, at).reshape(acc["count"], width)

    prim = doc["meshes"][0]["primitives"][0]
    assert prim.get("mode", 4) == 4
    positions = accessor(prim["attributes"]["POSITION"]).astype(np.float64)
    if "indices" in prim:
        triangles = accessor(prim["indices"]).astype(np.int64).reshape(-1, 3)
    else:
        triangles = np.arange(len(positions)).reshape(-1, 3)
    return smoothffd.Mesh(positions, triangles)
