"""Input meshes: positions, faces of any size, split normals, UVs, per-vertex weights."""

import numpy as np

from ._validate import float_array, int_array


class Mesh:
    """A polygon mesh to deform.

    positions: (V, 3). faces: (F, 3) triangles, or a pair (corner_vertices (C,),
    face_offsets (F + 1,)) for polygons of any size (convex or concave; triangulated inside).
    corner_normals: (C, 3) one per face corner (Blender's split normals); None means smooth
    area-weighted vertex normals. A vertex is sharp where its corners carry different normals.
    uvs: (C, 2) or None. vertex_weights: (V,) per-vertex deformation factor (Blender's vertex
    group), default 1.
    """

    def __init__(self, positions, faces, corner_normals=None, uvs=None, vertex_weights=None):
        self.positions = float_array(positions, "positions", shape=(None, 3))
        V = len(self.positions)
        if isinstance(faces, tuple) and len(faces) == 2:
            cv = int_array(faces[0], "faces[0] (corner_vertices)", shape=(None,))
            fo = int_array(faces[1], "faces[1] (face_offsets)", shape=(None,))
            if len(fo) < 1 or fo[0] != 0 or fo[-1] != len(cv):
                raise ValueError("faces[1] (face_offsets): must start at 0 and end at the number "
                                 "of corners")
            sizes = np.diff(fo)
            if np.any(sizes < 3):
                bad = int(np.argmax(sizes < 3))
                raise ValueError(f"faces: face {bad} has {int(sizes[bad])} corners (at least 3 needed)")
        else:
            tris = int_array(faces, "faces", shape=(None, 3))
            cv = tris.reshape(-1)
            fo = np.arange(0, len(cv) + 1, 3, dtype=np.int32)
        if len(fo) <= 1:
            raise ValueError("faces: the mesh has no faces")
        if cv.size and (cv.min() < 0 or cv.max() >= V):
            raise ValueError(f"faces: vertex index out of range [0, {V}) "
                             f"(min {int(cv.min())}, max {int(cv.max())})")
        self.corner_vertices, self.face_offsets = cv, fo
        C = len(cv)
        self.corner_normals = None
        if corner_normals is not None:
            self.corner_normals = float_array(corner_normals, "corner_normals", shape=(C, 3),
                                              dtype=np.float32)
        self.uvs = None
        if uvs is not None:
            self.uvs = float_array(uvs, "uvs", shape=(C, 2), dtype=np.float32)
        self.vertex_weights = None
        if vertex_weights is not None:
            self.vertex_weights = float_array(vertex_weights, "vertex_weights", shape=(V,),
                                              dtype=np.float32)
            w = self.vertex_weights
            if w.size and (w.min() < 0 or w.max() > 1):
                raise ValueError(f"vertex_weights: must lie in [0, 1] (a deformation factor), got "
                                 f"values from {w.min():.6g} to {w.max():.6g}")

    @property
    def vertex_count(self):
        return len(self.positions)

    @property
    def face_count(self):
        return len(self.face_offsets) - 1

    def __repr__(self):
        return f"Mesh({self.vertex_count} vertices, {self.face_count} faces)"
