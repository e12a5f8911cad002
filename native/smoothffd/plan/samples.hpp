// The samples of a plan (paper sec. 5.1; plan.hpp: samples, constrained fitting): the points
// at which the evaluators evaluate the lattice, shared between neighbouring patches, and which
// polynomial piece of the lattice each lies in.
//
// Patch p's column k (plan/fit_matrix.hpp) lies at barycentric numerators q over 3n of its
// corners. Its sample is
//   at a corner (two numerators 0): the sub-vertex, sample v in [0, SV);
//   on the patch's edge e (one numerator 0): one of the edge's ES inner points, whose
//     numerators over 3n along it are the multiples of 3 and n, 2n, numbered j from end a:
//     sample SV + e ES + j;
//   inside: the patch's own, SV + E ES + p IS + (its order among the inside columns),
//     IS = (n - 1)(n - 2) / 2.
// So the two patches on an edge read the very same samples along it. Positions and weights are
// linear in the corners' (the sub-vertices on the rest surface).
#pragma once

#include <vector>

#include "smoothffd/lattice/lattice_spec.hpp"
#include "smoothffd/plan/fit_matrix.hpp"
#include "smoothffd/plan/plan.hpp"
#include "smoothffd/plan/sub_vertices.hpp"

namespace sffd {

// The numerators over 3n of the samples inside an edge, increasing (ES of them).
std::vector<int> edge_sample_numerators(int n);

// Needs plan.patch_vertex, patch_edge, patch_edge_reversed, edge_vertex (build_adjacency).
// Fills plan.sample_position, sample_weight, patch_samples, edge_constraint (the samples at
// 1/3 and 2/3 from end a), fit_matrix, column_bary, samples, fit_degree, columns and
// edge_samples. Returns the samples' positions in double (S x 3). Throws
// std::invalid_argument past 2e9 samples.
// Given a lattice, also locates each sample as locate_samples does, in the same pass (its
// position is then still in cache), with local coordinates where the sub-vertices need them
// (needs_local_coordinates: the other samples are convex combinations of them). held: a plan
// of the same sub-mesh in another pose (a plan that follows with its pieces held, before it
// gives its arrays up): its patch_samples and edge_constraint are taken over, and each
// sample is looked for first in the piece it had there; ignored where its tables' sizes
// differ. keep_exact false (with a lattice): returns nothing.
std::vector<double> build_samples(Plan& plan, const FitTables& fit, const SubVertices& sub,
                                  const LatticeSpec* lattice = nullptr, const Plan* held = nullptr,
                                  bool keep_exact = true);

// Whether the evaluators' float arithmetic (t from the float position and the float map,
// about 2^-24 (|ds/dp| |p| + |b - shift| + |origin - shift|) / scale of the span) cannot place
// the points `pos` (S x 3) within 2^-11 of some span of the lattice.
bool needs_local_coordinates(const LatticeSpec& lattice, const std::vector<double>& pos);

// Fills plan.sample_piece (each sample's piece per axis, 10 bits each) and, where
// needs_local_coordinates, plan.sample_local (each sample's local coordinate t in its piece,
// computed in double from its exact position); else sample_local stays empty.
void locate_samples(Plan& plan, const LatticeSpec& lattice, const std::vector<double>& sample_exact);

}  // namespace sffd
