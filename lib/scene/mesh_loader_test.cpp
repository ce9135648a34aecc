#include "scene/mesh_loader.h"

#include <gtest/gtest.h>

#include <filesystem>

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
  EXPECT_EQ(r.material_files, std::vector<std::string>{"CornellBox-Sphere.mtl"});
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

}  // namespace
}  // namespace tessera
