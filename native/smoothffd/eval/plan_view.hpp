// Raw-pointer views of a plan and of the per-frame buffers: the same structs describe host
// memory (CPU evaluator) and device memory (CUDA evaluator).
#pragma once

#include <cstdint>

#include "smoothffd/core/isa.hpp"
#include "smoothffd/plan/plan.hpp"

namespace sffd {

struct PlanView {
  int input_vertices, sub_vertices, patches, edges, samples, columns, level, grid;
  int output_vertices, output_triangles, render_vertices;
  const AxisPieceF* pieces;
  int axis_offset[3], dims[3];
  int components;  // control values a point: 3, or 4 with point weights (Plan::components)
  float param_map[12];
  const float* sample_position;
  const uint32_t* sample_piece;
  const float* sample_weight;
  const float* sample_local;  // S x 3, or null: t of each sample in its pieces (Plan::sample_local)
  const float* fit_matrix;
  const float* column_bary;
  const int* patch_samples;
  const int* patch_vertex;
  const int* patch_edge;
  const uint8_t* patch_edge_reversed;
  const float* patch_render_normal;
  const float* patch_adjust_normal;
  const int* edge_vertex;
  const int* edge_constraint;
  const int* edge_patch;
  const uint8_t* edge_slot;
  const uint8_t* edge_flags;
  const float* grid_basis;
  const int* local_triangles;
  const int* output_owner;
  const int* render_owner;       // R x 2
  const int* render_position;    // R
  const int* patch_grid_render;  // P x G
  const int* render_triangles;   // T x 3
  // Centre rows (Plan::centre_row; null without them: point weights, or a device view)
  const uint64_t* centre_box;
  const long long* centre_start;
  const float* centre_row;
  const float* centre_constant;
};

// Intermediate and output buffers of one frame.
struct FrameView {
  float* sample_value;     // S x 3: F at the samples
  float* sample_jacobian;  // S x 9: dF/dp (row-major)
  float* edge_control;     // E x 2 x 3: adjusted edge control points (near a, near b)
  float* patch_control;    // P x 10 x 3: geometry patches
  float* patch_normal;     // P x 10 x 3: normal patches
  float* positions;        // N x 3
  float* corner_normals;   // T x 3 x 3
};

SFFD_ISA_BEGIN

// Host view of a plan's vectors (the CUDA evaluator builds the same from device copies).
inline PlanView host_view(const Plan& p) {
  PlanView v{};
  v.input_vertices = p.input_vertices;
  v.sub_vertices = p.sub_vertices;
  v.patches = p.patches;
  v.edges = p.edges;
  v.samples = p.samples;
  v.columns = p.columns;
  v.level = p.level;
  v.grid = p.grid;
  v.output_vertices = p.output_vertices;
  v.output_triangles = p.output_triangles;
  v.render_vertices = p.render_vertices;
  v.pieces = p.pieces.data();
  for (int a = 0; a < 3; ++a) {
    v.axis_offset[a] = p.axis_offset[a];
    v.dims[a] = p.dims[a];
  }
  v.components = p.components;
  for (int i = 0; i < 12; ++i) v.param_map[i] = p.param_map[i];
  v.sample_position = p.sample_position.data();
  v.sample_piece = p.sample_piece.data();
  v.sample_weight = p.sample_weight.data();
  v.sample_local = p.sample_local.empty() ? nullptr : p.sample_local.data();
  v.fit_matrix = p.fit_matrix.data();
  v.column_bary = p.column_bary.data();
  v.patch_samples = p.patch_samples.data();
  v.patch_vertex = p.patch_vertex.data();
  v.patch_edge = p.patch_edge.data();
  v.patch_edge_reversed = p.patch_edge_reversed.data();
  v.patch_render_normal = p.patch_render_normal.data();
  v.patch_adjust_normal = p.patch_adjust_normal.data();
  v.edge_vertex = p.edge_vertex.data();
  v.edge_constraint = p.edge_constraint.data();
  v.edge_patch = p.edge_patch.data();
  v.edge_slot = p.edge_slot.data();
  v.edge_flags = p.edge_flags.data();
  v.grid_basis = p.grid_basis.data();
  v.local_triangles = p.local_triangles.data();
  v.output_owner = p.output_owner.data();
  v.render_owner = p.render_owner.data();
  v.render_position = p.render_position.data();
  v.patch_grid_render = p.patch_grid_render.data();
  v.render_triangles = p.render_triangles.data();
  v.centre_box = p.centre_box.empty() ? nullptr : p.centre_box.data();
  v.centre_start = p.centre_start.empty() ? nullptr : p.centre_start.data();
  v.centre_row = p.centre_row.empty() ? nullptr : p.centre_row.data();
  v.centre_constant = p.centre_constant.empty() ? nullptr : p.centre_constant.data();
  return v;
}

SFFD_ISA_END

}  // namespace sffd
