// SPDX-License-Identifier: Apache-2.0
#include "scene/mesh_loader.h"

#include <gtest/gtest.h>

#include <unistd.h>

#include <filesystem>
#include <fstream>

#include "scene/scene_parser.h"

namespace tessera {
namespace {

namespace fs = std::filesystem;
const fs::path kSource = TESSERA_SOURCE_DIR;

TEST(MeshLoader, EveryEdgeCaseObjLoadsOrFailsCleanly) {
  // Files that break naive loaders (tinyobjloader's test models): NaN coordinates, zero and
  // out-of-range indices, invalid faces, missing MTL, concave polygons, lines, points, w.
  const fs::path dir = kSource / "tests/data/obj-edge-cases";
  int loaded = 0, refused = 0;
  for (const auto& entry : fs::directory_iterator(dir)) {
    if (entry.path().extension() != ".obj") continue;
    SCOPED_TRACE(entry.path().filename().string());
    try {
      const MeshLoadResult r = load_mesh(entry.path().string());
      ++loaded;
      ASSERT_GT(r.mesh.triangle_count(), 0u);
      ASSERT_EQ(r.mesh.material_ids.size(), r.mesh.triangle_count());
      for (uint32_t i : r.mesh.indices) ASSERT_LT(i, r.mesh.positions.size());
      for (const auto& p : r.mesh.positions) ASSERT_TRUE(is_finite(p));
      for (uint32_t m : r.mesh.material_ids) ASSERT_LT(m, r.materials.size());
    } catch (const SceneError& e) {
      ++refused;
      // The message names the file.
      EXPECT_NE(std::string(e.what()).find(entry.path().filename().string()), std::string::npos) << e.what();
    }
  }
  EXPECT_GE(loaded, 5);
  EXPECT_GE(refused, 1);  // e.g. line-prim.obj has no surface at all
  std::printf("edge-case OBJs: %d loaded, %d refused cleanly\n", loaded, refused);
}

TEST(MeshLoader, NanVerticesAreDroppedDeterministically) {
  const MeshLoadResult r = load_mesh((kSource / "tests/data/obj-edge-cases/test-nan.obj").string());
  EXPECT_GT(r.dropped_nonfinite, 0u);
}

TEST(MeshLoader, LinesAndPointsAreNotSurfaces) {
  EXPECT_THROW(load_mesh((kSource / "tests/data/obj-edge-cases/line-prim.obj").string()), SceneError);
  EXPECT_THROW(load_mesh((kSource / "tests/data/obj-edge-cases/points-prim.obj").string()), SceneError);
}

TEST(MeshLoader, CornellBoxMaterialsMapFromMtl) {
  const MeshLoadResult r = load_mesh((kSource / "scenes/models/CornellBox-Sphere.obj").string());
  int mirrors = 0, glass = 0, emitters = 0;
  for (const auto& m : r.materials) {
    if (m.type == Material::Type::kMirror) {
      ++mirrors;
      EXPECT_FLOAT_EQ(m.reflectance.x, 0.95f);  // Ks
    }
    if (m.type == Material::Type::kGlass) {
      ++glass;
      EXPECT_FLOAT_EQ(float(m.ior), 2.5f);  // Ni
    }
    if (m.is_emissive()) {
      ++emitters;
      EXPECT_FLOAT_EQ(m.emission.x, 10.0f);  // Ke
    }
  }
  EXPECT_EQ(mirrors, 1);
  EXPECT_EQ(glass, 1);
  EXPECT_EQ(emitters, 1);
  EXPECT_EQ(r.side_files, std::vector<std::string>{"CornellBox-Sphere.mtl"});
  // Excluding the two tessellated spheres leaves the box: 7 quads = 14 triangles... plus none.
  const MeshLoadResult box =
      load_mesh((kSource / "scenes/models/CornellBox-Sphere.obj").string(), {"leftSphere", "rightSphere"});
  EXPECT_LT(box.mesh.triangle_count(), 40u);
  EXPECT_GT(r.mesh.triangle_count(), 1000u);
}

TEST(MeshLoader, AsciiPlyWithCrlfAndExtraProperties) {
  const MeshLoadResult r = load_mesh((kSource / "scenes/models/bun_zipper.ply").string());
  EXPECT_EQ(r.mesh.positions.size(), 35947u);
  EXPECT_GE(r.mesh.triangle_count(), 69000u);
}

TEST(MeshLoader, BinaryBigEndianPlyWithPerFaceProperty) {
  const fs::path armadillo = kSource / "../shared/data/armadillo/Armadillo.ply";
  if (!fs::exists(armadillo)) GTEST_SKIP() << "no " << armadillo << " (only in the development checkout)";
  const MeshLoadResult r = load_mesh(armadillo.string());
  EXPECT_EQ(r.mesh.triangle_count() + r.dropped_degenerate, 345944u);
}

TEST(MeshLoader, MissingFileIsNamed) {
  try {
    load_mesh("/no/such/mesh.obj");
    FAIL();
  } catch (const SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("/no/such/mesh.obj: mesh file not found"), std::string::npos);
  }
}

// Side files (an OBJ's mtllib, a glTF's buffers) are opened by assimp itself: with confinement
// every one must lie in the bundle, also through "..", absolute paths and symlinks.
class MeshConfinement : public ::testing::Test {
 protected:
  void SetUp() override {
    root_ = fs::temp_directory_path() / ("tessera_confine_" + std::to_string(::getpid()));
    fs::remove_all(root_);
    fs::create_directories(root_ / "bundle");
    write("outside.mtl", "newmtl red\nKd 1 0 0\n");
    write("bundle/inside.mtl", "newmtl green\nKd 0 1 0\n");
    const float tri[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    write("buf.bin", std::string(reinterpret_cast<const char*>(tri), sizeof tri));
  }
  void TearDown() override { fs::remove_all(root_); }
  void write(const std::string& rel, const std::string& text) {
    std::ofstream(root_ / rel, std::ios::binary) << text;
  }
  std::string obj_using(const std::string& mtllib) {
    write("bundle/m.obj", "mtllib " + mtllib + "\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl x\nf 1 2 3\n");
    return (root_ / "bundle/m.obj").string();
  }
  void expect_refused(const std::string& mesh, const std::string& named) {
    try {
      load_mesh(mesh, {}, (root_ / "bundle").string());
      FAIL() << mesh << " loaded although it refers to " << named;
    } catch (const SceneError& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find("outside the scene bundle"), std::string::npos) << what;
      EXPECT_NE(what.find(named), std::string::npos) << what;
      EXPECT_EQ(what.rfind(mesh, 0), 0u) << what;  // the message starts with the mesh file
    }
  }
  fs::path root_;
};

TEST_F(MeshConfinement, ObjMaterialLibraryOutsideTheBundleIsRefused) {
  const std::string mesh = obj_using("../outside.mtl");
  // Unconfined (a local render) the library is read: the test's files are valid.
  const MeshLoadResult open = load_mesh(mesh);
  bool red = false;
  for (const Material& m : open.materials) red = red || (m.albedo.x == 1.0f && m.albedo.y == 0.0f);
  EXPECT_TRUE(red);
  expect_refused(mesh, "outside.mtl");
  // An absolute mtllib: assimp's OBJ reader joins it to the OBJ's directory, so it names a file
  // inside the bundle that does not exist. Either way nothing outside may be read.
  try {
    const MeshLoadResult r = load_mesh(obj_using((root_ / "outside.mtl").string()), {}, (root_ / "bundle").string());
    for (const Material& m : r.materials) EXPECT_FALSE(m.albedo.x == 1.0f && m.albedo.y == 0.0f) << m.name;
  } catch (const SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("outside the scene bundle"), std::string::npos) << e.what();
  }
}

TEST_F(MeshConfinement, SymlinkOutOfTheBundleIsRefused) {
  fs::create_symlink(root_ / "outside.mtl", root_ / "bundle/link.mtl");
  expect_refused(obj_using("link.mtl"), "link.mtl");
}

TEST_F(MeshConfinement, SideFilesInsideTheBundleLoad) {
  const MeshLoadResult r = load_mesh(obj_using("inside.mtl"), {}, (root_ / "bundle").string());
  EXPECT_EQ(r.mesh.triangle_count(), 1u);
  ASSERT_EQ(r.side_files.size(), 1u);
  EXPECT_EQ(r.side_files[0], "inside.mtl");
}

// A glTF with one triangle in an external buffer at `uri`.
std::string gltf_with_buffer(const std::string& uri) {
  return R"({"asset": {"version": "2.0"},
    "buffers": [{"uri": ")" + uri + R"(", "byteLength": 36}],
    "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36}],
    "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                   "min": [0, 0, 0], "max": [1, 1, 0]}],
    "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
    "nodes": [{"mesh": 0}], "scenes": [{"nodes": [0]}], "scene": 0})";
}

TEST_F(MeshConfinement, GltfBufferOutsideTheBundleIsRefused) {
  write("bundle/t.gltf", gltf_with_buffer("../buf.bin"));
  const std::string mesh = (root_ / "bundle/t.gltf").string();
  const MeshLoadResult open = load_mesh(mesh);
  EXPECT_EQ(open.mesh.triangle_count(), 1u);
  EXPECT_EQ(open.side_files, std::vector<std::string>{"../buf.bin"});
  expect_refused(mesh, "buf.bin");
}

// Side files are reported whatever the format, so a bundle carries a glTF's buffers too.
TEST_F(MeshConfinement, GltfBufferInsideTheBundleIsASideFile) {
  fs::create_directories(root_ / "bundle/data");
  fs::copy_file(root_ / "buf.bin", root_ / "bundle/data/buf.bin");
  write("bundle/t.gltf", gltf_with_buffer("data/buf.bin"));
  const MeshLoadResult r = load_mesh((root_ / "bundle/t.gltf").string(), {}, (root_ / "bundle").string());
  EXPECT_EQ(r.mesh.triangle_count(), 1u);
  EXPECT_EQ(r.side_files, std::vector<std::string>{"data/buf.bin"});
}

}  // namespace
}  // namespace tessera
