// The CUDA evaluator's tables from a plan (device_tables.hpp): plain C++, built by the core
// (native/tests checks them) and by libsmoothffd_cuda.so.
#include "smoothffd/cuda/device_tables.hpp"

#include <algorithm>
#include <atomic>
#include <stdexcept>
#include <unordered_map>

#include "smoothffd/core/parallel.hpp"
#include "smoothffd/plan/bezier.hpp"

namespace sffd {
namespace cuda_impl {

namespace {

// The walk of the tessellation grid: gi[w].order is the grid point at walk position w, the
// boundary points (corners and edge points, in the grid's order) first, then the interior
// points by their ordinal.
std::vector<GridInfo> build_grid_info(const Plan& p, const TessellationTables& tt) {
  std::vector<GridInfo> gi(tt.points.size());
  for (size_t g = 0; g < gi.size(); ++g) gi[g] = {tt.points[g].kind, tt.points[g].which, tt.points[g].step, -1};
  const int IG = (p.level - 1) * (p.level - 2) / 2, NB = (int)gi.size() - IG;
  int nb = 0;
  for (size_t g = 0; g < gi.size(); ++g) {
    if (gi[g].kind == 2 && gi[g].which >= 0 && gi[g].which < IG)
      gi[NB + gi[g].which].order = (int)g;
    else if (gi[g].kind != 2 && nb < NB)
      gi[nb++].order = (int)g;
  }
  for (const GridInfo& q : gi)
    if (q.order < 0) throw std::logic_error("CudaEvaluator: unexpected tessellation grid");
  return gi;
}

// PatchRender of every patch from the plan's render vertices; every (patch, grid point) is
// checked: it writes render vertex r exactly when render_owner[r] is that pair.
std::vector<PatchRender> build_patch_render(const Plan& p, const TessellationTables& tt) {
  const int P = p.patches, G = p.grid, L = p.level;
  const long long shift = (long long)p.render_vertices - p.output_vertices;
  std::vector<PatchRender> pr((size_t)P);
  auto owner_is = [&](int r, int pp, int g) {
    return p.render_owner[2 * (size_t)r] == pp && p.render_owner[2 * (size_t)r + 1] == g;
  };
  std::atomic<bool> bad{false};  // no throwing inside the worker threads
  parallel_for(P, default_threads(), [&](long long b, long long e) {
    for (long long pp = b; pp < e; ++pp) {
      PatchRender& x = pr[pp];
      const int* gr = &p.patch_grid_render[(size_t)pp * G];
      for (int k = 0; k < 3; ++k) x.corner[k] = x.edge_base[k] = -1, x.edge_stride[k] = 0;
      for (int g = 0; g < G; ++g) {
        const GridPoint& q = tt.points[g];
        if (q.kind == 0 && owner_is(gr[g], (int)pp, g)) x.corner[q.which] = gr[g];
        if (q.kind == 1) {
          int m = p.patch_edge_reversed[3 * pp + q.which] ? L - q.step : q.step;
          if (m == 1 && owner_is(gr[g], (int)pp, g)) x.edge_base[q.which] = gr[g];
          if (m == 2) x.edge_stride[q.which] = gr[g];
        }
      }
      for (int k = 0; k < 3; ++k)
        if (L > 2) {
          int g1 = -1;
          for (int g = 0; g < G; ++g)
            if (tt.points[g].kind == 1 && tt.points[g].which == k &&
                (p.patch_edge_reversed[3 * pp + k] ? L - tt.points[g].step : tt.points[g].step) == 1)
              g1 = g;
          x.edge_stride[k] -= gr[g1];
        }
      for (int g = 0; g < G; ++g) {  // the check
        const GridPoint& q = tt.points[g];
        bool rev = q.kind == 1 && p.patch_edge_reversed[3 * pp + q.which];
        long long r = -1;
        if (q.kind == 2) {
          r = p.patch_grid_vertex[(size_t)pp * G + g] + shift;
        } else if (q.kind == 0) {
          r = x.corner[q.which];
        } else if (x.edge_base[q.which] >= 0) {
          int m = rev ? L - q.step : q.step;
          r = x.edge_base[q.which] + (long long)(m - 1) * x.edge_stride[q.which];
        }
        bool owns = owner_is(gr[g], (int)pp, g);
        if (owns != (r >= 0) || (owns && r != gr[g])) bad = true;
      }
    }
  });
  if (bad) throw std::logic_error("CudaEvaluator: render vertex table not in the layout of plan.hpp");
  return pr;
}

// The inline kernel's per-patch records (InlinePatch). owns: bit k, the patch writes the
// points of its edge k; corner_owns: bit k, the position of its corner k.
std::vector<InlinePatch> build_patch_records(const Plan& p, const std::vector<uint8_t>& owns,
                                             const std::vector<PatchRender>& pr,
                                             const std::vector<uint8_t>& corner_owns) {
  std::vector<InlinePatch> rec((size_t)p.patches);
  for (int q = 0; q < p.patches; ++q) {
    InlinePatch& r = rec[q];
    r = InlinePatch{};
    for (int i = 0; i < 9; ++i) {
      r.rest[i] = p.patch_render_normal[9 * (size_t)q + i];
      r.adjust[i] = p.patch_adjust_normal[9 * (size_t)q + i];
    }
    uint32_t f = owns[q] | uint32_t(corner_owns[q]) << 8;
    const int L = p.level;
    for (int k = 0; k < 3; ++k) {
      const int e = p.patch_edge[3 * (size_t)q + k], k1 = (k + 1) % 3;
      const bool rev = p.patch_edge_reversed[3 * (size_t)q + k] != 0;
      r.vertex[k] = p.patch_vertex[3 * (size_t)q + k];
      // PatchBoundary: the point at step s from corner k is step m = s (rev: L - s) from the
      // edge's end a, output vertex sub_vertices + e (L - 1) + m - 1 and render vertex
      // edge_base + (m - 1) edge_stride.
      const int ob = p.sub_vertices + e * (L - 1), rb = pr[q].edge_base[k], rs = pr[q].edge_stride[k];
      const bool owned = (owns[q] >> k) & 1;
      r.bound.edge[k] = I4{owned ? (rev ? ob + L - 1 : ob - 1) : -1, owned ? (rev ? -1 : 1) : 0,
                           rb >= 0 ? (rev ? rb + (L - 1) * rs : rb - rs) : -1, rb >= 0 ? (rev ? -rs : rs) : 0};
      r.bound.corner[k] = pr[q].corner[k];
      // -1 means "writes nothing" to the kernel and the boundary lists: a base it writes to
      // must not be negative (render vertices of edge points come after the sub-vertices').
      if ((owned && r.bound.edge[k].x < 0) || (rb >= 0 && r.bound.edge[k].z < 0))
        throw std::logic_error("CudaEvaluator: unexpected render table");
      const int p0 = p.edge_patch[2 * (size_t)e], p1 = p.edge_patch[2 * (size_t)e + 1];
      const uint8_t ef = p.edge_flags[e];
      const bool self1 = p1 == q;
      uint32_t bits = (ef & kSharpAtA ? 1u : 0u) | (ef & kSharpAtB ? 2u : 0u) | (ef & kKeepFitted ? 4u : 0u) |
                      (p1 >= 0 ? 8u : 0u);
      if (!(ef & kNonManifold)) {
        // This patch's corner at each end must be the slot the edge table has for its side.
        const int ka = rev ? k1 : k, kb = rev ? k : k1, side = self1 ? 1 : 0;
        if ((self1 ? p1 : p0) != q || p.edge_slot[4 * (size_t)e + 2 * side] != ka ||
            p.edge_slot[4 * (size_t)e + 2 * side + 1] != kb)
          throw std::logic_error("CudaEvaluator: unexpected edge table");
        if (p1 >= 0) {
          const int other = self1 ? p0 : p1;
          for (int end = 0; end < 2; ++end) {
            const int slot = p.edge_slot[4 * (size_t)e + 2 * (1 - side) + end];
            for (int i = 0; i < 3; ++i) r.nb[k][3 * end + i] = p.patch_adjust_normal[9 * (size_t)other + 3 * slot + i];
          }
        }
      }
      f |= (rev ? 8u : 0u) << k | bits << (12 + 4 * k) | (self1 ? 1u : 0u) << (24 + k);
    }
    r.flags = f;
  }
  return rec;
}

// Each patch record's corner samples and the box of each evaluated column's sample
// (InlinePatch::corner, box), and the check that inline_sample_point puts every sample where
// the plan has it (within rounding: the plan rounds its double positions to float), so that
// the shared-memory modes need no per-sample records. False when a sample is not where
// expected.
bool place_samples(const Plan& p, const DeviceTables& t, const std::vector<uint32_t>& box_of,
                   std::vector<InlinePatch>& rec) {
  const int K = p.columns;
  std::atomic<bool> ok{true};
  parallel_for(p.patches, default_threads(), [&](long long b, long long e) {
    for (long long q = b; q < e; ++q) {
      InlinePatch& r = rec[q];
      for (int c = 0; c < 3; ++c) {
        const size_t v = (size_t)p.patch_vertex[3 * q + c];
        r.corner[c] = F4{p.sample_position[3 * v], p.sample_position[3 * v + 1], p.sample_position[3 * v + 2],
                         p.sample_weight[v]};
      }
      std::fill(std::begin(r.box), std::end(r.box), uint8_t(0));
      for (size_t i = 0; i < t.evaluated.size(); ++i) {
        const size_t s = (size_t)p.patch_samples[(size_t)q * K + t.evaluated[i]];
        r.box[i] = (uint8_t)box_of[s];
        const F4 x = inline_sample_point(t.column[t.evaluated[i]], r.flags, r.corner[0], r.corner[1], r.corner[2]);
        const float got[4] = {x.x, x.y, x.z, x.w};
        for (int a = 0; a < 4; ++a) {
          const float want = a < 3 ? p.sample_position[3 * s + a] : p.sample_weight[s];
          const float scale = std::max({1.0f, std::fabs(r.corner[0].x), std::fabs(r.corner[0].y),
                                        std::fabs(r.corner[0].z), std::fabs(want)});
          if (!(std::fabs(got[a] - want) <= 2e-6f * scale)) ok = false;
        }
      }
    }
  });
  return ok;
}

// Whether the constraint columns of every patch are its corners and its edges' 1/3 and 2/3
// samples in the order k_inline reads them (plan/fit_matrix.hpp).
bool constraint_columns_as_expected(const Plan& p) {
  const int K = p.columns, K0 = K - 9;
  if (K0 < 0) return false;
  for (int q = 0; q < p.patches; ++q) {
    const int* col = p.patch_samples.data() + (size_t)q * K + K0;
    for (int k = 0; k < 3; ++k) {
      const int e = p.patch_edge[3 * q + k];
      const bool rev = p.patch_edge_reversed[3 * q + k];
      const int ka = rev ? (k + 1) % 3 : k, kb = rev ? k : (k + 1) % 3;
      if (col[k] != p.patch_vertex[3 * q + k]) return false;
      if (p.edge_vertex[2 * e] != p.patch_vertex[3 * q + ka] || p.edge_vertex[2 * e + 1] != p.patch_vertex[3 * q + kb])
        return false;
      if (col[3 + 2 * k] != p.edge_constraint[2 * e + (rev ? 1 : 0)] ||
          col[4 + 2 * k] != p.edge_constraint[2 * e + (rev ? 0 : 1)])
        return false;
    }
  }
  return true;
}

// The columns: where each sample lies, the duplicates among the constraint columns, the
// kernel's order, M_r's constraint part.
void build_columns(const Plan& p, DeviceTables& t) {
  const int K = p.columns, K0 = K - 9;
  ColumnMap& cm = t.column_map;
  std::fill(std::begin(cm.con_of), std::end(cm.con_of), int8_t(-1));
  // Constraint columns that are grid points with the same sample in every patch.
  t.evaluated.clear();
  for (int k = 0; k < K0; ++k) t.evaluated.push_back(k);
  for (int j = 0; j < 9; ++j) {
    int dup = -1;
    for (int k = 0; k < K0 && dup < 0; ++k) {
      bool same = true;
      for (int c = 0; c < 3; ++c) same = same && p.column_bary[3 * k + c] == p.column_bary[3 * (K0 + j) + c];
      for (int q = 0; same && q < p.patches; ++q)
        same = p.patch_samples[(size_t)q * K + k] == p.patch_samples[(size_t)q * K + K0 + j];
      if (same) dup = k;
    }
    if (dup >= 0)
      cm.con_of[dup] = int8_t(j);
    else
      t.evaluated.push_back(K0 + j);
  }
  if (K0 > kMaxInlineGrid || (int)t.evaluated.size() > kMaxInlineColumns)
    throw std::logic_error("CudaEvaluator: more fitting columns than the fitting degree allows");
  // Where each column's sample lies (InlineColumn): its barycentric point has exactly 1 at a
  // corner and exactly 0 at the corner opposite an edge; the edge parameter is the plan's
  // numerator over 3n, from either end.
  const int N3 = 3 * p.fit_degree;
  t.column.assign((size_t)K, InlineColumn{});
  for (int k = 0; k < K; ++k) {
    const float* b = &p.column_bary[3 * (size_t)k];
    InlineColumn& c = t.column[k];
    c.bary = F4{b[0], b[1], b[2], k < K0 ? p.fit_matrix[(size_t)kCentre * K + k] : 0.0f};
    c.t_fwd = c.t_rev = 0.0f;
    c.edge = c.corner = -1;
    for (int i = 0; i < 3; ++i) {
      if (b[i] == 1.0f) c.corner = i;
      if (b[i] == 0.0f && b[(i + 1) % 3] != 0.0f && b[(i + 2) % 3] != 0.0f) {
        c.edge = (i + 1) % 3;  // the edge from corner i + 1 to i + 2
        const long long q = std::llround((double)b[(i + 2) % 3] * N3);  // the far corner's numerator
        c.t_fwd = (float)(q / (double)N3);
        c.t_rev = (float)((N3 - q) / (double)N3);
      }
    }
  }
  // The kernel's order of the evaluated columns: corners, edge points, interior points.
  auto kind = [&](int k) { return t.column[k].corner >= 0 ? 0 : t.column[k].edge >= 0 ? 1 : 2; };
  std::stable_sort(t.evaluated.begin(), t.evaluated.end(), [&](int a, int b) { return kind(a) < kind(b); });
  for (size_t i = 0; i < t.evaluated.size(); ++i) cm.order[i] = uint8_t(t.evaluated[i]);
  cm.n_cols = uint8_t(t.evaluated.size());
  // M_r's last 9 columns, and the sum of its six edge rows in the order finish_patch_from
  // adds the fitted edge control points (edge k: the point next to corner k, then k + 1).
  for (int r = 0; r < 10; ++r)
    for (int q = 0; q < 9; ++q) t.mrow[r][q] = p.fit_matrix[(size_t)r * K + K0 + q];
  for (int q = 0; q < 9; ++q) {
    float s = 0.0f;
    for (int k = 0; k < 3; ++k) s += t.mrow[edge_control_index(k, false)][q] + t.mrow[edge_control_index(k, true)][q];
    t.mrow[10][q] = s;
  }
}

// Axis pieces in the kernel's form: t = dot(map.xyz, p) + map.w, the coefficients (zero beyond
// the piece's own) and each term's offset in the control values.
void build_pieces(const Plan& p, DeviceTables& t) {
  const int n_pieces = (int)p.pieces.size();
  const int stride[3] = {p.dims[1] * p.dims[2], p.dims[2], 1};
  t.pieces.assign((size_t)n_pieces, InlinePiece{});
  t.pieces_wide.assign((size_t)n_pieces, InlinePieceWide{});
  for (int a = 0; a < 3; ++a) {
    const int end = a < 2 ? p.axis_offset[a + 1] : n_pieces;
    for (int i = p.axis_offset[a]; i < end; ++i) {
      const AxisPieceF& src = p.pieces[i];
      InlinePieceWide& d = t.pieces_wide[i];
      const float* m = p.param_map + 4 * a;
      const double s = src.inv_scale;
      d.map = src.degree == 0 ? F4{0, 0, 0, 0}
                              : F4{(float)(m[0] * s), (float)(m[1] * s), (float)(m[2] * s),
                                   (float)(((double)m[3] - src.origin) * s)};
      for (int k = 0; k < kMaxTerms; ++k) {
        for (int q = 0; q < kMaxTerms; ++q) d.coef[k][q] = src.coef[k][q];
        d.off[k] = src.index[k] * stride[a];
      }
      InlinePiece& n = t.pieces[i];
      n.map = d.map;
      for (int k = 0; k < 4; ++k) n.coef[k] = F4{d.coef[k][0], d.coef[k][1], d.coef[k][2], d.coef[k][3]};
      n.off = I4{d.off[0], d.off[1], d.off[2], d.off[3]};
    }
  }
}

}  // namespace

int plan_max_terms(const Plan& p) {
  int m = 1;
  for (const AxisPieceF& pc : p.pieces) m = std::max(m, std::max(pc.count, pc.degree + 1));
  return m;
}

size_t DeviceTables::shared_bytes(bool boxes) const {
  // Control values (weights), pieces, columns, the walk's (s, t) and boundary GridInfo, the box
  // polynomials (boxes) and their list, in 16-byte units; a group's boundary list; the
  // ColumnMap. With boxes the control values are staged in the block's ctrl table only while
  // the boxes are computed.
  const size_t C = (size_t)terms, nbox = box_list.size();
  const size_t units = (boxes ? 0 : (size_t)points) + 6 * (size_t)n_pieces + 2 * (size_t)columns +
                       ((size_t)st_count + 1) / 2 + (size_t)walk_boundary + (boxes ? nbox * C * C * C : 0) + nbox;
  return 16 * units + 2 * (size_t)list_stride() + sizeof(ColumnMap);
}

DeviceTables build_device_tables(const Plan& p, const TessellationTables& tt) {
  DeviceTables t;
  t.grid_info = build_grid_info(p, tt);
  t.owns.assign((size_t)p.patches, 0);
  const long long edge_points = (long long)p.edges * (p.level - 1);
  for (long long i = 0; i < edge_points; ++i) {
    int pp = p.output_owner[2 * i], g = p.output_owner[2 * i + 1];
    if (pp < 0 || g < 0 || t.grid_info[g].kind != 1)
      throw std::logic_error("CudaEvaluator: unexpected output owner table");
    t.owns[pp] |= uint8_t(1u << t.grid_info[g].which);
  }
  t.render = build_patch_render(p, tt);
  t.render_shift = (long long)p.render_vertices - p.output_vertices;
  t.max_terms = plan_max_terms(p);
  t.terms = kernel_terms(t.max_terms);
  t.points = p.dims[0] * p.dims[1] * p.dims[2];
  t.n_pieces = (int)p.pieces.size();
  t.columns = p.columns;
  if (!constraint_columns_as_expected(p)) {
    t.no_inline = "the plan's constraint columns are not where the inline kernel reads them";
    return t;
  }
  if (p.components != 3) {
    // Blender's lattice vertex group: the reference kernels evaluate the points' weights with
    // the displacements (stages.hpp); the inline kernel's tables hold 3 values a point.
    t.no_inline = "the lattice has point weights (a vertex group): the reference kernels evaluate them";
    return t;
  }
  // The boxes that hold samples, numbered in order of first use; box_of[s]: sample s's.
  std::vector<uint32_t> box_of((size_t)p.samples);
  {
    std::unordered_map<uint32_t, uint32_t> index;
    for (int s = 0; s < p.samples; ++s) {
      auto it = index.emplace(p.sample_piece[s], (uint32_t)t.box_list.size());
      if (it.second) {
        int b[3];
        for (int a = 0; a < 3; ++a) b[a] = p.axis_offset[a] + (int)((p.sample_piece[s] >> (10 * a)) & 1023u);
        t.box_list.push_back(I4{b[0], b[1], b[2], b[0] | b[1] << 10 | b[2] << 20});
      }
      box_of[s] = it.first->second;
    }
  }
  const int interior_points = (p.level - 1) * (p.level - 2) / 2, boundary_points = p.grid - interior_points;
  t.walk_boundary = boundary_points;
  t.st_interior = (boundary_points + 1) / 2 * 2;
  t.st_count = t.st_interior + interior_points;
  build_columns(p, t);
  build_pieces(p, t);
  // The shared-memory modes: at most 4 terms an axis, every piece in the boxes' 10 bits, the
  // boundary list's 11 bits of walk position, InlinePatch::box (a byte a column, an index
  // into at most 256 boxes).
  if (!p.sample_local.empty())
    // The shared-memory modes place each sample from its patch's corners and compute its t
    // from the float position; the global mode reads the plan's local coordinates, as the
    // CPU does (sample_weights, stages.hpp).
    t.shared_why = "knot spans too small for float positions: the samples' local coordinates come from the plan";
  else if (t.max_terms > 4)
    t.shared_why = "more than 4 terms an axis";
  else if (t.n_pieces >= 1024)
    t.shared_why = "1024 or more axis pieces";
  else if (boundary_points > 2048)
    t.shared_why = "more than 2048 boundary points a patch";
  else if (t.box_list.size() > 256)
    t.shared_why = "more than 256 lattice boxes hold samples";
  else if ((int)t.evaluated.size() > kMaxBoxColumns)
    t.shared_why = "more columns a patch than the patch records hold";
  // Corner ownership (the first patch of each sub-vertex writes its position) and the loose
  // sub-vertices (in no patch: a kernel of their own writes them).
  std::vector<uint8_t> mine((size_t)p.patches, 0);
  std::vector<char> seen((size_t)p.sub_vertices, 0);
  for (int q = 0; q < p.patches; ++q)
    for (int k = 0; k < 3; ++k) {
      const int v = p.patch_vertex[3 * q + k];
      if (!seen[v]) {
        seen[v] = 1;
        mine[q] |= uint8_t(1u << k);
      }
    }
  for (int v = 0; v < p.sub_vertices; ++v)
    if (!seen[v]) t.loose.push_back(v);
  t.patch_rec = build_patch_records(p, t.owns, t.render, mine);
  if (t.shared_why.empty() && !place_samples(p, t, box_of, t.patch_rec))
    t.shared_why = "a sample is not where the patch's corners place it";
  // The walk's (s, t) table (WalkST), an even number of entries (copied as 16-byte pieces),
  // and its boundary points' GridInfo.
  t.grid_st.assign((size_t)(t.st_count + 1) / 2 * 2, F2{0.0f, 0.0f});
  std::vector<GridInfo> walk((size_t)p.grid);
  for (int w = 0; w < p.grid; ++w) {
    const size_t g = (size_t)t.grid_info[w].order;
    const int i = w < boundary_points ? w : t.st_interior + (w - boundary_points);
    t.grid_st[i] = F2{(float)tt.bary[3 * g + 1], (float)tt.bary[3 * g + 2]};
    walk[w] = t.grid_info[g];
  }
  t.grid_walk.assign(walk.begin(), walk.begin() + boundary_points);
  return t;
}

InlineMode choose_inline_mode(DeviceTables& t, size_t budget) {
  if (!t.no_inline.empty()) return kInlineNone;
  if (!t.shared_why.empty()) return kInlineGlobal;
  if (t.points <= kBoxPoints && t.shared_bytes(true) <= budget) return kInlineBoxes;
  if (t.shared_bytes(false) <= budget) return kInlineWeights;
  t.shared_why = "the lattice and grid tables do not fit in shared memory";
  return kInlineGlobal;
}

std::vector<uint16_t> build_boundary_lists(DeviceTables& t) {
  const int NB = t.walk_boundary, stride = t.list_stride();
  const long long P = (long long)t.patch_rec.size(), groups = (P + 31) / 32;
  std::vector<uint16_t> list((size_t)groups * stride, 0);
  for (long long g = 0; g < groups; ++g) {
    int n = 0;
    const int q_end = (int)std::min<long long>(32, P - g * 32);
    for (int q = 0; q < q_end; ++q) {
      const PatchBoundary& b = t.patch_rec[(size_t)(g * 32 + q)].bound;
      for (int w = 0; w < NB; ++w) {
        const GridInfo& gi = t.grid_walk[w];
        const bool writes = gi.kind == 0 ? b.corner[gi.which] >= 0 : b.edge[gi.which].x >= 0 || b.edge[gi.which].z >= 0;
        if (writes) list[(size_t)g * stride + n++] = uint16_t(q | w << 5);
      }
    }
    for (int q = 0; q < q_end; ++q) t.patch_rec[(size_t)(g * 32 + q)].bound.items = n;
  }
  return list;
}

}  // namespace cuda_impl
}  // namespace sffd
