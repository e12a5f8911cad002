// The plan build's input checks (plan/validate.hpp): what each refuses, and that good input
// passes.
#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <string>

#include "smoothffd/plan/validate.hpp"
#include "test_util.hpp"

using namespace sffd;
using namespace sffd_test;

namespace {

// The message check_input_mesh throws for m, or "" when it accepts it.
std::string mesh_error(const InputMesh& m) {
  try {
    check_input_mesh(m);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

std::string lattice_error(const LatticeSpec& s) {
  try {
    check_lattice_structure(s);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

bool starts_with(const std::string& s, const char* prefix) { return s.rfind(prefix, 0) == 0; }

}  // namespace

TEST(Validate, GoodMeshesPass) {
  EXPECT_EQ(mesh_error(octahedron()), "");
  EXPECT_EQ(mesh_error(cube_quads()), "");
  InputMesh m = cube_quads();
  m.corner_normal.assign(3 * 24, 0.0f);
  m.corner_uv.assign(2 * 24, 0.5f);
  m.vertex_weight.assign(8, 2.0f);
  EXPECT_EQ(mesh_error(m), "");
}

TEST(Validate, EachMeshArrayIsCheckedByName) {
  const InputMesh ok = octahedron();  // 6 vertices, 8 triangles, 24 corners
  InputMesh m = ok;
  m.positions.pop_back();
  EXPECT_TRUE(starts_with(mesh_error(m), "positions:")) << mesh_error(m);
  m = ok;
  m.positions[7] = NAN;
  EXPECT_TRUE(starts_with(mesh_error(m), "positions:")) << mesh_error(m);
  m = ok;
  m.positions[0] = -INFINITY;
  EXPECT_TRUE(starts_with(mesh_error(m), "positions:")) << mesh_error(m);
  m = ok;
  m.face_offset = {1, 24};
  EXPECT_TRUE(starts_with(mesh_error(m), "face_offsets:")) << mesh_error(m);
  m = ok;
  m.face_offset.back() = 23;
  EXPECT_TRUE(starts_with(mesh_error(m), "face_offsets:")) << mesh_error(m);
  m = ok;
  m.face_offset = {0, 3, 5, 24};  // face 1 has two corners
  EXPECT_EQ(mesh_error(m), "faces: face 1 has fewer than 3 corners");
  m = ok;
  m.corner_vertex[10] = 6;
  EXPECT_EQ(mesh_error(m), "faces: vertex index out of range");
  m = ok;
  m.corner_vertex[0] = -1;
  EXPECT_EQ(mesh_error(m), "faces: vertex index out of range");
  m = ok;
  m.corner_normal.assign(3 * 24 - 1, 0.0f);
  EXPECT_TRUE(starts_with(mesh_error(m), "corner_normals:")) << mesh_error(m);
  m = ok;
  m.corner_uv.assign(3 * 24, 0.0f);  // three values a corner: not UVs
  EXPECT_TRUE(starts_with(mesh_error(m), "uvs:")) << mesh_error(m);
  m = ok;
  m.vertex_weight.assign(5, 1.0f);
  EXPECT_TRUE(starts_with(mesh_error(m), "vertex_weights:")) << mesh_error(m);
}

TEST(Validate, LatticeStructure) {
  EXPECT_EQ(lattice_error(bspline_box(2, 5)), "");
  EXPECT_EQ(lattice_error(blender_box(BlenderInterp::BSpline, 4)), "");
  LatticeSpec s = bspline_box(2, 5);
  s.components = 4;
  EXPECT_EQ(lattice_error(s), "");
  s.components = 2;
  EXPECT_TRUE(starts_with(lattice_error(s), "lattice: components")) << lattice_error(s);
  // 1024 knot spans on the w axis: one more than Plan::sample_piece's 10 bits hold.
  LatticeSpec many = bspline_box(1, 1025);
  EXPECT_GE(many.axes[2].pieces().size(), 1024u);
  EXPECT_TRUE(starts_with(lattice_error(many), "lattice: too many knot spans")) << lattice_error(many);
  LatticeSpec fits = bspline_box(1, 1000);
  EXPECT_EQ(lattice_error(fits), "");
}

TEST(Validate, LatticeBeyondFloatRangeNamesTheAxis) {
  LatticeSpec s = bspline_box(2, 4);
  std::vector<double> tiny = clamped_knots(2, 4);
  for (double& k : tiny) k *= 1e-40;  // spans of 5e-41: 1 / scale is no float
  s.axes[1] = AxisBasis::bspline(2, tiny, 4);
  const std::string e = lattice_error(s);
  EXPECT_TRUE(starts_with(e, "lattice: axis v has a knot span")) << e;
  LatticeSpec m = bspline_box(2, 4);
  m.object_to_param[2][3] = 1e39;  // beyond FLT_MAX (3.4e38)
  EXPECT_TRUE(starts_with(lattice_error(m), "lattice: the object-to-parameter map")) << lattice_error(m);
  m.object_to_param[2][3] = 1e37;
  EXPECT_EQ(lattice_error(m), "");
}
