#include "smoothffd/plan/samples.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <mutex>
#include <stdexcept>

#include "smoothffd/core/cancel.hpp"
#include "smoothffd/core/parallel.hpp"
#include "smoothffd/plan/lattice_tables.hpp"

namespace sffd {
namespace {

uint32_t pack_pieces(const int p[3]) { return uint32_t(p[0]) | uint32_t(p[1]) << 10 | uint32_t(p[2]) << 20; }

constexpr uint32_t kNoHint = ~0u;

// Sample s's pieces (and, with local, its local coordinates) from its position: the double
// one with local, else the float one the evaluators read (plan.sample_position, already
// written). hint: a packed guess of its pieces (kNoHint: none).
// Returns whether the pieces found are the hint.
bool locate_sample(Plan& plan, const LatticeSpec& lattice, long long s, const double* exact, bool local, uint32_t hint) {
  double pos[3], prm[3];
  int pc[3];
  for (int i = 0; i < 3; ++i) pos[i] = local ? exact[i] : plan.sample_position[3 * s + i];
  lattice.to_param(pos, prm);
  for (int a = 0; a < 3; ++a) pc[a] = lattice.axes[a].find_piece(prm[a], hint == kNoHint ? -1 : int((hint >> (10 * a)) & 1023u));
  const uint32_t packed = pack_pieces(pc);
  plan.sample_piece[s] = packed;
  if (local)
    for (int a = 0; a < 3; ++a) {
      const AxisPiece& piece = lattice.axes[a].pieces()[pc[a]];
      plan.sample_local[3 * s + a] = piece.degree == 0 ? 0.0f : (float)((prm[a] - piece.origin) / piece.scale);
    }
  return packed == hint;
}

}  // namespace

std::vector<int> edge_sample_numerators(int n) {
  std::vector<int> num;
  for (int q = 1; q < 3 * n; ++q)
    if (q % 3 == 0 || q == n || q == 2 * n) num.push_back(q);
  return num;
}

std::vector<double> build_samples(Plan& plan, const FitTables& fit, const SubVertices& sub, const LatticeSpec* lattice,
                                  const Plan* held, bool keep_exact) {
  const int n = fit.n, K = fit.columns, N3 = 3 * n;
  const int SV = (int)sub.weight.size(), E = (int)(plan.edge_vertex.size() / 2), P = (int)(plan.patch_vertex.size() / 3);
  const std::vector<double>& moved = sub.position;
  const std::vector<double>& sub_weight = sub.weight;
  const std::vector<int> edge_num = edge_sample_numerators(n);
  const int ES = (int)edge_num.size(), IS = (n - 1) * (n - 2) / 2;
  auto edge_index = [&](int q) { return int(std::lower_bound(edge_num.begin(), edge_num.end(), q) - edge_num.begin()); };
  const long long S = (long long)SV + (long long)E * ES + (long long)P * IS;
  if (S > 2000000000LL) throw std::invalid_argument("mesh: too large for one plan");
  // A held plan's samples are these samples in another pose when its tables have their sizes
  // (the same sub-mesh, so the same edges and patches in the same order).
  if (held && !(held->samples == S && held->patch_samples.size() == (size_t)P * K &&
                held->edge_constraint.size() == 2 * (size_t)E))
    held = nullptr;
  const std::vector<uint32_t>* piece_hint = held && held->sample_piece.size() == (size_t)S ? &held->sample_piece : nullptr;
  if (!lattice) keep_exact = true;
  plan.sample_position.resize(3 * S);
  std::vector<double> sample_exact(keep_exact ? 3 * S : 0);  // the positions before rounding to float
  plan.sample_weight.resize(S);
  // Every sample is a convex combination of sub-vertices (which are samples themselves): they
  // decide whether the evaluators need local coordinates.
  const bool local = lattice && needs_local_coordinates(*lattice, moved);
  if (lattice) {
    plan.sample_piece.resize(S);
    if (local) plan.sample_local.resize(3 * S);
    else plan.sample_local.clear();
  }
  // The samples not in the pieces they had in the held plan: each thread's, then joined.
  std::mutex repieced_mutex;
  std::vector<int> repieced;
  // known: the sample's pieces where its corners tell them (below), else kNoHint: looked for.
  auto put_sample = [&](long long s, const double* pos, double w, std::vector<int>& moved_piece,
                        uint32_t known = kNoHint) {
    for (int i = 0; i < 3; ++i) plan.sample_position[3 * s + i] = (float)pos[i];
    if (keep_exact)
      for (int i = 0; i < 3; ++i) sample_exact[3 * s + i] = pos[i];
    plan.sample_weight[s] = (float)w;
    if (!lattice) return;
    const uint32_t hint = piece_hint ? (*piece_hint)[s] : kNoHint;
    bool same;
    if (known != kNoHint) {
      plan.sample_piece[s] = known;
      same = known == hint;
    } else {
      same = locate_sample(plan, *lattice, s, pos, local, hint);
    }
    if (!same && piece_hint) moved_piece.push_back((int)s);
  };
  auto join = [&](std::vector<int>& moved_piece) {
    if (moved_piece.empty()) return;
    std::lock_guard<std::mutex> lock(repieced_mutex);
    repieced.insert(repieced.end(), moved_piece.begin(), moved_piece.end());
  };
  // Each sub-vertex, edge and patch writes its own samples: in parallel, the same values.
  const int threads = default_threads();
  parallel_for(SV, threads, [&](long long b, long long e) {
    std::vector<int> moved_piece;
    for (long long v = b; v < e; ++v) put_sample(v, &moved[3 * (size_t)v], sub_weight[v], moved_piece);
    join(moved_piece);
  });
  // Where the samples are located from their float positions (no local coordinates): each
  // sub-vertex deep inside its lattice box, so far from the box's planes that every convex
  // combination of such points in one box, rounded to float and mapped to the lattice's
  // parameters, is in that box (find_piece's answer there). The samples of an edge or a patch
  // whose corners are all deep in one box take its pieces without a search: most of them.
  std::vector<uint8_t> deep;
  if (lattice && !local) {
    double R = 0;
    for (double x : moved) R = std::max(R, std::fabs(x));
    // How far (in parameters) such a sample may lie outside its corners' computed parameters:
    // the float rounding of its position and of theirs (2^-24 R each, times the map's row
    // norm), and the double arithmetic, all with room to spare.
    double margin[3];
    for (int a = 0; a < 3; ++a) {
      const double* A = lattice->object_to_param[a];
      const double G = std::fabs(A[0]) + std::fabs(A[1]) + std::fabs(A[2]);
      margin[a] = std::ldexp(G * R, -21) + 64 * std::numeric_limits<double>::epsilon() * (G * R + std::fabs(A[3]));
    }
    deep.assign(SV, 0);
    parallel_for(SV, threads, [&](long long b, long long e) {
      for (long long v = b; v < e; ++v) {
        double pos[3], prm[3];
        for (int i = 0; i < 3; ++i) pos[i] = plan.sample_position[3 * v + i];
        lattice->to_param(pos, prm);
        const uint32_t k = plan.sample_piece[v];
        bool in = true;
        for (int a = 0; a < 3 && in; ++a) in = lattice->axes[a].inside_piece(prm[a], int((k >> (10 * a)) & 1023u), margin[a]);
        deep[v] = in;
      }
    });
  }
  // The pieces of the box the given corners are all deep in, else kNoHint.
  auto common_box = [&](const int* corner, int n) {
    if (deep.empty()) return kNoHint;
    const uint32_t k = plan.sample_piece[corner[0]];
    for (int c = 0; c < n; ++c)
      if (!deep[corner[c]] || plan.sample_piece[corner[c]] != k) return kNoHint;
    return k;
  };
  parallel_for(E, threads, [&](long long eb, long long ee) {
    std::vector<int> moved_piece;
    for (long long e = eb; e < ee; ++e) {
      int a = plan.edge_vertex[2 * e], b = plan.edge_vertex[2 * e + 1];
      const uint32_t known = common_box(&plan.edge_vertex[2 * e], 2);
      for (int j = 0; j < ES; ++j) {
        double t = edge_num[j] / double(N3), pos[3];
        for (int i = 0; i < 3; ++i) pos[i] = (1 - t) * moved[3 * (size_t)a + i] + t * moved[3 * (size_t)b + i];
        put_sample(SV + e * ES + j, pos, (1 - t) * sub_weight[a] + t * sub_weight[b], moved_piece, known);
      }
    }
    join(moved_piece);
  });
  // The inside columns (all numerators positive), in column order: the patches' own samples.
  std::vector<int> inside;
  for (int k = 0; k < K; ++k) {
    const int* q = &fit.numerator[3 * k];
    if (q[0] > 0 && q[1] > 0 && q[2] > 0) inside.push_back(k);
  }
  // Which sample each column of each patch reads: the held plan's, else from the sub-mesh.
  if (held) {
    plan.patch_samples = held->patch_samples;
    plan.edge_constraint = held->edge_constraint;
  } else {
    std::vector<int> column_interior(K, -1);
    for (int o = 0; o < IS; ++o) column_interior[inside[o]] = o;
    plan.patch_samples.resize((size_t)P * K);
    parallel_for(P, threads, [&](long long pb, long long pe) {
      for (long long p = pb; p < pe; ++p) {
        const int* cv = &plan.patch_vertex[3 * p];
        for (int k = 0; k < K; ++k) {
          const int* q = &fit.numerator[3 * k];
          long long s;
          int zeros = (q[0] == 0) + (q[1] == 0) + (q[2] == 0);
          if (zeros == 2) {
            s = cv[q[0] ? 0 : q[1] ? 1 : 2];
          } else if (zeros == 1) {
            int ek = q[2] == 0 ? 0 : q[0] == 0 ? 1 : 2;  // edge corner ek -> ek + 1
            int along = q[(ek + 1) % 3];                  // numerator of the far corner
            if (plan.patch_edge_reversed[3 * p + ek]) along = N3 - along;
            s = SV + (long long)plan.patch_edge[3 * p + ek] * ES + edge_index(along);
          } else {
            s = SV + (long long)E * ES + (long long)p * IS + column_interior[k];
          }
          plan.patch_samples[(size_t)p * K + k] = (int)s;
        }
      }
    });
    plan.edge_constraint.resize(2 * (size_t)E);
    for (int e = 0; e < E; ++e) {
      plan.edge_constraint[2 * e] = SV + e * ES + edge_index(n);
      plan.edge_constraint[2 * e + 1] = SV + e * ES + edge_index(2 * n);
    }
  }
  parallel_for(P, threads, [&](long long pb, long long pe) {
    std::vector<int> moved_piece;
    for (long long p = pb; p < pe; ++p) {
      const int* cv = &plan.patch_vertex[3 * p];
      const uint32_t known = common_box(cv, 3);
      for (int o = 0; o < IS; ++o) {
        const int* q = &fit.numerator[3 * inside[o]];
        const double b[3] = {q[0] / double(N3), q[1] / double(N3), q[2] / double(N3)};
        double pos[3], w = 0;
        for (int i = 0; i < 3; ++i) {
          pos[i] = 0;
          for (int c = 0; c < 3; ++c) pos[i] += b[c] * moved[3 * (size_t)cv[c] + i];
        }
        for (int c = 0; c < 3; ++c) w += b[c] * sub_weight[cv[c]];
        put_sample(SV + (long long)E * ES + p * IS + o, pos, w, moved_piece, known);
      }
    }
    join(moved_piece);
  });
  plan.fit_matrix.assign(fit.M_r.begin(), fit.M_r.end());
  plan.column_bary.resize(3 * (size_t)K);
  for (int i = 0; i < 3 * K; ++i) plan.column_bary[i] = (float)(fit.numerator[i] / double(N3));
  // Where the indexing is the held plan's: its samples_id as the base, and the samples whose
  // pieces are not those they had there.
  plan.samples_id = new_table_id();
  plan.samples_base_id = held && piece_hint ? held->samples_id : 0;
  std::sort(repieced.begin(), repieced.end());
  plan.repieced_samples = std::move(repieced);
  plan.samples = (int)S;
  plan.fit_degree = n;
  plan.columns = K;
  plan.edge_samples = ES;
  return sample_exact;
}

bool needs_local_coordinates(const LatticeSpec& lattice, const std::vector<double>& pos) {
  double R = 0;
  for (double x : pos) R = std::max(R, std::fabs(x));
  for (int a = 0; a < 3; ++a) {
    const double* A = lattice.object_to_param[a];
    const double G = std::fabs(A[0]) + std::fabs(A[1]) + std::fabs(A[2]);
    const double shift = float_shift(lattice.axes[a]);
    for (const AxisPiece& pc : lattice.axes[a].pieces()) {
      if (pc.degree == 0) continue;
      const double err = G * R + std::fabs(A[3] - shift) + std::fabs(pc.origin - shift);
      if (err > std::ldexp(pc.scale, 13)) return true;
    }
  }
  return false;
}

void locate_samples(Plan& plan, const LatticeSpec& lattice, const std::vector<double>& sample_exact) {
  const long long S = (long long)(sample_exact.size() / 3);
  const bool local = needs_local_coordinates(lattice, sample_exact);
  plan.sample_piece.resize(S);
  if (local) plan.sample_local.resize(3 * S);
  parallel_for(S, default_threads(), [&](long long b, long long e) {
    for (long long s = b; s < e; ++s) locate_sample(plan, lattice, s, &sample_exact[3 * s], local, kNoHint);
  });
}

}  // namespace sffd
