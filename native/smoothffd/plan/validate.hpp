// The first stage of the plan build: the checks of its input, before any work. Each throws
// std::invalid_argument saying which argument is wrong and why.
#pragma once

#include "smoothffd/lattice/lattice_spec.hpp"
#include "smoothffd/mesh/triangulate.hpp"
#include "smoothffd/plan/plan.hpp"

namespace sffd {

// The mesh's arrays: positions #V x 3 and finite, face offsets from 0 to the corner count with
// at least 3 corners a face, vertex indices in range, one normal and one UV a corner and one
// weight a vertex where given.
void check_input_mesh(const InputMesh& mesh);

// A triangulation given for the mesh (a plan's, kept for the same connectivity in a new pose):
// each triangle's face in range and its three corners distinct corners of that face, at most
// n - 2 triangles a face of n corners. What it cannot tell from another mesh of the same
// counts (the caller compares the connectivity) it does not claim to.
void check_triangulation(const InputMesh& mesh, const Triangulation& tr);

// A lattice structure the plan and its evaluators can hold: at most 1023 polynomial pieces
// (knot spans) an axis (Plan::sample_piece's 10 bits), 3 or 4 components, and every value of
// its float tables (plan/lattice_tables.hpp) a finite float.
void check_lattice_structure(const LatticeSpec& lattice);

}  // namespace sffd
