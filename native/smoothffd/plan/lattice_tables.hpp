// The lattice tables of a plan (plan.hpp: pieces, axis_offset, dims, components, param_map):
// the lattice structure in float, as the evaluators read it.
//
// The float tables measure each axis's parameter from a shift (float_shift): its first knot
// plane when that lies further from 0 than the planes' extent, else 0 (ordinary lattices:
// unchanged tables). In float, s = A p + b near 1e4 has steps of 1e-3: a B-spline axis with
// knots at -13451.4916 + [0, 2.4e-4] lost its spans to rounding (input vertices 0.76 off in a
// lattice 2 wide); from its first plane it keeps them.
#pragma once

#include "smoothffd/lattice/lattice_spec.hpp"
#include "smoothffd/plan/plan.hpp"

namespace sffd {

// The shift an axis's float parameter is measured from (see above).
double float_shift(const AxisBasis& axis);

// Fills plan.pieces (each axis's pieces, shifted, 1 / scale, padded terms index 0), axis_offset,
// dims, components and param_map (rows [A | b - shift]).
void build_lattice_tables(Plan& plan, const LatticeSpec& lattice);

}  // namespace sffd
