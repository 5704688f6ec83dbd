// Mitsuba 3 import: every supported element, imported and rendered, gives the image of the
// hand-written invr scene it stands for (bit for bit, same seed); conversions (fov axes, frames,
// transform order) against their formulas; bad files are errors naming file, line and element.
#include "core/io/mitsuba_import.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "core/error.h"
#include "core/image/image.h"
#include "core/diff/parameters.h"
#include "core/io/job_io.h"
#include "core/render/renderer.h"
#include "core/scene/scene_builder.h"

namespace invr {
namespace {

namespace fs = std::filesystem;

fs::path tmpDir() {
  static fs::path dir = [] {
    fs::path d = fs::temp_directory_path() / ("invr_mitsuba_test_" + std::to_string(::getpid()));
    fs::create_directories(d);
    return d;
  }();
  return dir;
}

void writeFile(const std::string& name, const std::string& text) {
  std::ofstream f(tmpDir() / name, std::ios::binary);
  f << text;
}

// Shared by both sides: a camera at (0, 0, 5) looking down -z, a 24x24 film, 4 spp, paths of two
// vertices after the camera (Mitsuba max_depth 3), Russian roulette after 4 bounces (rr_depth 5).
const char* kXmlCamera = R"(
  <integrator type="path"><integer name="max_depth" value="3"/></integrator>
  <sensor type="perspective">
    <float name="fov" value="40"/>
    <transform name="to_world"><lookat origin="0, 0, 5" target="0, 0, 0" up="0, 1, 0"/></transform>
    <sampler type="independent"><integer name="sample_count" value="4"/></sampler>
    <film type="hdrfilm"><integer name="width" value="24"/><integer name="height" value="24"/><rfilter type="box"/></film>
  </sensor>)";
const char* kJsonCamera = R"("views": [{"eye": {"z": 5}, "target": {"z": 4}, "up": {"y": 1}, "fov_y_degrees": 40}],
  "film": {"width": 24, "height": 24})";
const char* kJsonRender = R"("render": {"spp": 4, "max_depth": 2, "russian_roulette_depth": 4})";

// A floor (twosided diffuse rectangle, scaled 2, turned to face +y, at y = -1) under a small area
// light facing down (no bsdf: Mitsuba's black default for emitters).
const char* kXmlRoom = R"(
  <bsdf type="twosided" id="floor_bsdf"><bsdf type="diffuse"><rgb name="reflectance" value="0.5, 0.25, 0.125"/></bsdf></bsdf>
  <shape type="rectangle" id="floor">
    <transform name="to_world"><scale value="2"/><rotate x="1" angle="-90"/><translate y="-1"/></transform>
    <ref id="floor_bsdf"/>
  </shape>
  <shape type="rectangle" id="lamp">
    <transform name="to_world"><scale value="0.5"/><rotate x="1" angle="90"/><translate y="1.5"/></transform>
    <emitter type="area"><rgb name="radiance" value="5"/></emitter>
  </shape>)";
const char* kJsonRoomMaterials = R"({"name": "floor_bsdf", "diffuse": {"albedo": {"constant": {"r": 0.5, "g": 0.25, "b": 0.125}}}},
  {"name": "default_emitter_black", "one_sided": true, "diffuse": {"albedo": {"value": 0}}})";
const char* kJsonRoomShapes = R"({"name": "floor", "quad": {}, "flip_tex_coords": true, "material": "floor_bsdf",
   "transform": {"matrix": [2, 0, 0, 0,  0, 0, 2, -1,  0, -2, 0, 0]}},
  {"name": "lamp", "quad": {}, "flip_tex_coords": true, "material": "default_emitter_black",
   "transform": {"matrix": [0.5, 0, 0, 0,  0, 0, -0.5, 1.5,  0, 0.5, 0, 0]}})";
const char* kJsonRoomLights = R"({"name": "lamp", "area": {"shape": "lamp", "radiance": {"r": 5, "g": 5, "b": 5}}})";

std::string xmlScene(const std::string& body, const std::string& camera = kXmlCamera) {
  return "<scene version=\"3.0.0\">" + camera + body + "\n</scene>\n";
}

Image renderJob(const v1::JobSpec& job) {
  AssetResolver assets;
  assets.baseDir = tmpDir();
  auto scene = buildJobScene(job, assets);
  return renderView(*scene, 0, renderOptionsFrom(job.render())).image;
}

MitsubaImport importText(const std::string& xml, const std::string& name = "scene.xml") {
  return importMitsubaSceneText(xml, tmpDir(), name);
}

// Renders the imported XML scene and the hand-written JSON scene and compares every pixel.
void expectSameImage(const std::string& xmlBody, const std::string& jsonMaterials, const std::string& jsonShapes,
                     const std::string& jsonLights, const std::string& render = kJsonRender) {
  MitsubaImport imp = importText(xmlScene(xmlBody));
  std::string json = std::string("{\"scene\": {") + kJsonCamera + ", \"materials\": [" + jsonMaterials + "], \"shapes\": [" + jsonShapes +
                     "], \"lights\": [" + jsonLights + "]}, " + render + "}";
  v1::JobSpec hand = parseJobJson(json, "hand.json");
  EXPECT_EQ(imp.job.render().spp(), hand.render().spp());
  EXPECT_EQ(imp.job.render().max_depth(), hand.render().max_depth());
  Image a = renderJob(imp.job), b = renderJob(hand);
  ASSERT_EQ(a.data().size(), b.data().size());
  size_t differ = 0;
  double sum = 0;
  for (size_t i = 0; i < a.data().size(); ++i) {
    differ += a.data()[i] != b.data()[i];
    sum += a.data()[i];
  }
  EXPECT_EQ(differ, 0u) << "imported:\n" << jobToJson(imp.job) << "\nhand-written:\n" << json;
  EXPECT_GT(sum, 0.0) << "the image is black: the comparison would prove nothing";
}

void expectSameWithRoom(const std::string& xmlObject, const std::string& jsonMaterials, const std::string& jsonShapes,
                        const std::string& jsonLights = kJsonRoomLights) {
  // Materials: the room's first (the importer adds them as shapes first use them), then the object's.
  expectSameImage(std::string(kXmlRoom) + xmlObject, std::string(kJsonRoomMaterials) + (jsonMaterials.empty() ? "" : ", " + jsonMaterials),
                  std::string(kJsonRoomShapes) + (jsonShapes.empty() ? "" : ", " + jsonShapes), jsonLights);
}

TEST(MitsubaImport, RectanglesTransformsTwosidedAndAreaLights) { expectSameWithRoom("", "", ""); }

// The rectangle faces away from the camera: one-sided, its back is black (as in Mitsuba).
TEST(MitsubaImport, CubeWithOneSidedDiffuse) {
  expectSameWithRoom(R"(<shape type="cube"><transform name="to_world"><scale value="0.5"/></transform>
      <bsdf type="diffuse" id="box_bsdf"><rgb name="reflectance" value="0.75 0.5 0.25"/></bsdf></shape>
      <shape type="rectangle" id="away"><transform name="to_world"><scale value="0.3"/><rotate y="1" angle="180"/><translate x="1.2" y="0.5"/></transform>
        <ref id="box_bsdf"/></shape>)",
                     R"({"name": "box_bsdf", "one_sided": true, "diffuse": {"albedo": {"constant": {"r": 0.75, "g": 0.5, "b": 0.25}}}})",
                     R"({"name": "cube_1", "box": {}, "material": "box_bsdf", "transform": {"matrix": [0.5,0,0,0, 0,0.5,0,0, 0,0,0.5,0]}},
                        {"name": "away", "quad": {}, "flip_tex_coords": true, "material": "box_bsdf", "transform": {"matrix": [-0.3,0,0,1.2, 0,0.3,0,0.5, 0,0,-0.3,0]}})");
}

TEST(MitsubaImport, SphereWithCentreRadiusAndSpectrumReflectance) {
  expectSameWithRoom(R"(<shape type="sphere" id="ball"><point name="center" x="0.25" y="0" z="0"/><float name="radius" value="0.5"/>
      <bsdf type="diffuse"><spectrum name="reflectance" value="0.5"/></bsdf></shape>)",
                     R"({"name": "bsdf_1", "one_sided": true, "diffuse": {"albedo": {"constant": {"r": 0.5, "g": 0.5, "b": 0.5}}}})",
                     R"({"name": "ball", "sphere": {"rings": 64}, "material": "bsdf_1", "transform": {"matrix": [0.5,0,0,0.25, 0,0.5,0,0, 0,0,0.5,0]}})");
}

TEST(MitsubaImport, DiskAndMatrixTransform) {
  expectSameWithRoom(R"(<shape type="disk" id="d"><transform name="to_world"><matrix value="0.5 0 0 0  0 0 0.5 -0.5  0 -0.5 0 0  0 0 0 1"/></transform>
      <bsdf type="diffuse" id="w"/></shape>)",
                     R"({"name": "w", "one_sided": true, "diffuse": {"albedo": {"constant": {"r": 0.5, "g": 0.5, "b": 0.5}}}})",
                     R"({"name": "d", "disk": {"segments": 128}, "material": "w", "transform": {"matrix": [0.5,0,0,0, 0,0,0.5,-0.5, 0,-0.5,0,0]}})");
}

// A tetrahedron without normals, as OBJ (smooth normals computed, as Mitsuba does; face_normals
// keeps it flat) and as binary big-endian PLY.
const char* kTetraObj = "v 0 0.5 0\nv -0.5 -0.5 0.5\nv 0.5 -0.5 0.5\nv 0 -0.5 -0.5\nf 1 2 3\nf 1 3 4\nf 1 4 2\nf 2 4 3\n";

TEST(MitsubaImport, ObjMeshesWithSmoothFaceAndFlippedNormals) {
  writeFile("tetra.obj", kTetraObj);
  expectSameWithRoom(R"(<shape type="obj" id="a"><string name="filename" value="tetra.obj"/>
        <transform name="to_world"><translate x="-0.6"/></transform><bsdf type="diffuse" id="m"/></shape>
      <shape type="obj" id="b"><string name="filename" value="tetra.obj"/><boolean name="face_normals" value="true"/>
        <transform name="to_world"><translate x="0.6"/></transform><ref id="m"/></shape>
      <shape type="obj" id="c"><string name="filename" value="tetra.obj"/><boolean name="flip_normals" value="true"/>
        <transform name="to_world"><translate y="0.6"/></transform><ref id="m"/></shape>)",
                     R"({"name": "m", "one_sided": true, "diffuse": {"albedo": {"value": 0.5}}})",
                     R"({"name": "a", "mesh": {"path": "tetra.obj"}, "smooth_normals": true, "material": "m", "transform": {"matrix": [1,0,0,-0.6, 0,1,0,0, 0,0,1,0]}},
                        {"name": "b", "mesh": {"path": "tetra.obj"}, "face_normals": true, "material": "m", "transform": {"matrix": [1,0,0,0.6, 0,1,0,0, 0,0,1,0]}},
                        {"name": "c", "mesh": {"path": "tetra.obj"}, "smooth_normals": true, "flip_normals": true, "material": "m", "transform": {"matrix": [1,0,0,0, 0,1,0,0.6, 0,0,1,0]}})");
}

TEST(MitsubaImport, PlyMeshesAndBitmapTexturesKeepMitsubasUvOrientation) {
  {
    std::string ply = "ply\nformat binary_big_endian 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
                      "property float u\nproperty float v\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";
    float v[4][5] = {{-1, -1, 0, 0, 0}, {1, -1, 0, 1, 0}, {1, 1, 0, 1, 1}, {-1, 1, 0, 0, 1}};
    auto be = [&](const void* p, size_t n) {
      const unsigned char* b = static_cast<const unsigned char*>(p);
      for (size_t i = n; i-- > 0;) ply += char(b[i]);
    };
    for (auto& row : v)
      for (float x : row) be(&x, 4);
    ply += char(4);
    for (int i : {0, 1, 2, 3}) be(&i, 4);
    writeFile("quad.ply", ply);
  }
  Image tex(4, 4, 3);  // a gradient: any flip of uv shows
  for (int y = 0; y < 4; ++y)
    for (int x = 0; x < 4; ++x) tex.setRgb(x, y, Rgb(0.1f + 0.2f * float(x), 0.1f + 0.2f * float(y), 0.5f));
  writeImage(tmpDir() / "grad.exr", tex);
  expectSameWithRoom(R"(<bsdf type="diffuse" id="tex"><texture type="bitmap" name="reflectance"><string name="filename" value="grad.exr"/></texture></bsdf>
      <shape type="ply" id="p"><string name="filename" value="quad.ply"/><transform name="to_world"><scale value="0.5"/><translate x="-0.6"/></transform><ref id="tex"/></shape>
      <shape type="rectangle" id="r"><transform name="to_world"><scale value="0.5"/><translate x="0.6"/></transform><ref id="tex"/></shape>)",
                     R"({"name": "tex", "one_sided": true, "diffuse": {"albedo": {"image": {"path": "grad.exr"}}}})",
                     R"({"name": "p", "mesh": {"path": "quad.ply"}, "smooth_normals": true, "flip_tex_coords": true, "material": "tex", "transform": {"matrix": [0.5,0,0,-0.6, 0,0.5,0,0, 0,0,0.5,0]}},
                        {"name": "r", "quad": {}, "flip_tex_coords": true, "material": "tex", "transform": {"matrix": [0.5,0,0,0.6, 0,0.5,0,0, 0,0,0.5,0]}})");
}

TEST(MitsubaImport, ConductorsPlasticsAndDielectric) {
  expectSameWithRoom(R"(
      <shape type="sphere" id="s1"><point name="center" x="-0.75" y="0" z="0"/><float name="radius" value="0.25"/><bsdf type="conductor"/></shape>
      <shape type="sphere" id="s2"><point name="center" x="-0.25" y="0" z="0"/><float name="radius" value="0.25"/>
        <bsdf type="roughconductor" id="rc"><string name="distribution" value="ggx"/><float name="alpha" value="0.25"/>
          <rgb name="eta" value="0.5, 1, 1.5"/><rgb name="k" value="4, 3, 2"/></bsdf></shape>
      <shape type="sphere" id="s3"><point name="center" x="0.25" y="0" z="0"/><float name="radius" value="0.25"/>
        <bsdf type="roughplastic" id="rp"><string name="distribution" value="ggx"/><float name="alpha" value="0.125"/>
          <rgb name="diffuse_reflectance" value="0.25, 0.5, 0.75"/><float name="int_ior" value="1.5"/><float name="ext_ior" value="1"/></bsdf></shape>
      <shape type="sphere" id="s4"><point name="center" x="0.75" y="0" z="0"/><float name="radius" value="0.25"/>
        <bsdf type="plastic" id="pl"><float name="int_ior" value="1.5"/><float name="ext_ior" value="1"/></bsdf></shape>
      <shape type="cube" id="glass"><transform name="to_world"><scale value="0.25"/><translate y="0.5"/></transform>
        <bsdf type="dielectric"><float name="int_ior" value="1.5"/><float name="ext_ior" value="1"/></bsdf></shape>)",
                     R"({"name": "bsdf_1", "one_sided": true, "mirror": {"reflectance": {"r": 1, "g": 1, "b": 1}}},
                        {"name": "rc", "one_sided": true, "rough_conductor": {"roughness": {"value": 0.25}, "eta": {"r": 0.5, "g": 1, "b": 1.5}, "k": {"r": 4, "g": 3, "b": 2}}},
                        {"name": "rp", "one_sided": true, "rough_plastic": {"albedo": {"constant": {"r": 0.25, "g": 0.5, "b": 0.75}}, "roughness": {"value": 0.125}, "ior": 1.5}},
                        {"name": "pl", "one_sided": true, "rough_plastic": {"albedo": {"value": 0.5}, "roughness": {"value": 0.01}, "ior": 1.5}},
                        {"name": "bsdf_2", "one_sided": true, "dielectric": {"ior": 1.5}})",
                     R"({"name": "s1", "sphere": {"rings": 64}, "material": "bsdf_1", "transform": {"matrix": [0.25,0,0,-0.75, 0,0.25,0,0, 0,0,0.25,0]}},
                        {"name": "s2", "sphere": {"rings": 64}, "material": "rc", "transform": {"matrix": [0.25,0,0,-0.25, 0,0.25,0,0, 0,0,0.25,0]}},
                        {"name": "s3", "sphere": {"rings": 64}, "material": "rp", "transform": {"matrix": [0.25,0,0,0.25, 0,0.25,0,0, 0,0,0.25,0]}},
                        {"name": "s4", "sphere": {"rings": 64}, "material": "pl", "transform": {"matrix": [0.25,0,0,0.75, 0,0.25,0,0, 0,0,0.25,0]}},
                        {"name": "glass", "box": {}, "material": "bsdf_2", "transform": {"matrix": [0.25,0,0,0, 0,0.25,0,0.5, 0,0,0.25,0]}})");
}

TEST(MitsubaImport, PointSpotConstantAndEnvironmentEmitters) {
  Image env(8, 4, 3);
  for (int y = 0; y < 4; ++y)
    for (int x = 0; x < 8; ++x) env.setRgb(x, y, Rgb(0.25f * float(x), 0.5f, 0.125f * float(y + 1)));
  writeImage(tmpDir() / "env.exr", env);
  expectSameImage(std::string(kXmlRoom) + R"(
      <emitter type="point" id="bulb"><point name="position" x="0" y="1" z="1"/><rgb name="intensity" value="4, 2, 1"/></emitter>
      <emitter type="spot" id="spot"><transform name="to_world"><lookat origin="0, 2, 0" target="0, 0, 0" up="0, 0, 1"/></transform>
        <rgb name="intensity" value="10"/><float name="cutoff_angle" value="30"/><float name="beam_width" value="20"/></emitter>
      <emitter type="constant" id="sky"><rgb name="radiance" value="0.25"/></emitter>
      <emitter type="envmap" id="map"><string name="filename" value="env.exr"/><float name="scale" value="0.5"/></emitter>)",
                  kJsonRoomMaterials, kJsonRoomShapes,
                  std::string(kJsonRoomLights) + R"(,
        {"name": "bulb", "point": {"position": {"y": 1, "z": 1}, "intensity": {"r": 4, "g": 2, "b": 1}}},
        {"name": "spot", "spot": {"position": {"y": 2}, "target": {"y": 1}, "intensity": {"r": 10, "g": 10, "b": 10}, "cone_outer_degrees": 30, "cone_inner_degrees": 20}},
        {"name": "sky", "constant_environment": {"radiance": {"r": 0.25, "g": 0.25, "b": 0.25}}},
        {"name": "map", "scale": 0.5, "environment": {"radiance": {"image": {"path": "env.exr"}}, "rotate_y_degrees": 180}})");
}

TEST(MitsubaImport, DefaultsSubstitutionRefsIncludesAndDirectIntegrator) {
  writeFile("included.xml", R"(<scene version="3.0.0"><bsdf type="diffuse" id="inc"><rgb name="reflectance" value="$albedo"/></bsdf></scene>)");
  std::string camera = R"(
  <default name="albedo" value="0.25, 0.5, 0.75"/>
  <default name="fov" value="40"/>
  <integrator type="direct"/>
  <sensor type="perspective">
    <float name="fov" value="$fov"/>
    <transform name="to_world"><lookat origin="0, 0, 5" target="0, 0, 0" up="0, 1, 0"/></transform>
    <sampler type="independent"><integer name="sample_count" value="4"/></sampler>
    <film type="hdrfilm"><integer name="width" value="24"/><integer name="height" value="24"/><rfilter type="box"/></film>
  </sensor>
  <include filename="included.xml"/>)";
  MitsubaImport imp = importText(xmlScene(std::string(kXmlRoom) + R"(<shape type="cube"><transform name="to_world"><scale value="0.5"/></transform><ref id="inc"/></shape>)", camera));
  std::string json = std::string("{\"scene\": {") + kJsonCamera + ", \"materials\": [" + kJsonRoomMaterials +
                     R"(, {"name": "inc", "one_sided": true, "diffuse": {"albedo": {"constant": {"r": 0.25, "g": 0.5, "b": 0.75}}}}], "shapes": [)" +
                     kJsonRoomShapes + R"(, {"name": "cube_1", "box": {}, "material": "inc", "transform": {"matrix": [0.5,0,0,0, 0,0.5,0,0, 0,0,0.5,0]}}], "lights": [)" +
                     kJsonRoomLights + R"(]}, "render": {"spp": 4, "max_depth": 1}})";
  v1::JobSpec hand = parseJobJson(json, "hand.json");
  EXPECT_EQ(imp.job.render().max_depth(), 1);
  Image a = renderJob(imp.job), b = renderJob(hand);
  EXPECT_EQ(a.data(), b.data());
  // -D style overrides win over <default>.
  MitsubaImportOptions opt;
  opt.defaults["fov"] = "60";
  MitsubaImport wide = importMitsubaSceneText(xmlScene(kXmlRoom, camera), tmpDir(), "scene.xml", opt);
  EXPECT_NEAR(wide.job.scene().views(0).fov_y_degrees(), 60.0, 1e-9);
}

// ------------------------------------------------------------------------ conversions

v1::Camera cameraOf(const std::string& sensorBody, int width, int height) {
  std::string xml = "<scene version=\"3.0.0\"><sensor type=\"perspective\">" + sensorBody +
                    "<film type=\"hdrfilm\"><integer name=\"width\" value=\"" + std::to_string(width) +
                    "\"/><integer name=\"height\" value=\"" + std::to_string(height) + "\"/><rfilter type=\"box\"/></film></sensor>" +
                    "<emitter type=\"constant\"/></scene>";
  return importText(xml).job.scene().views(0);
}

TEST(MitsubaImport, FovAxesBecomeTheVerticalFieldOfView) {
  const double deg = 180.0 / M_PI;
  // 32x16 film, fov 90: tan(45) = 1 along the named axis.
  EXPECT_NEAR(cameraOf(R"(<float name="fov" value="90"/>)", 32, 16).fov_y_degrees(), 2 * std::atan(0.5) * deg, 1e-9);  // x is the default
  EXPECT_NEAR(cameraOf(R"(<float name="fov" value="90"/><string name="fov_axis" value="y"/>)", 32, 16).fov_y_degrees(), 90, 1e-9);
  EXPECT_NEAR(cameraOf(R"(<float name="fov" value="90"/><string name="fov_axis" value="diagonal"/>)", 32, 16).fov_y_degrees(),
              2 * std::atan(1 / std::sqrt(5.0)) * deg, 1e-9);
  EXPECT_NEAR(cameraOf(R"(<float name="fov" value="90"/><string name="fov_axis" value="smaller"/>)", 32, 16).fov_y_degrees(), 90, 1e-9);
  EXPECT_NEAR(cameraOf(R"(<float name="fov" value="90"/><string name="fov_axis" value="larger"/>)", 32, 16).fov_y_degrees(),
              2 * std::atan(0.5) * deg, 1e-9);
  // No fov: a 50 mm lens on 35 mm film, across the 43.27 mm diagonal.
  double diag = std::tan(0.5 * 2 * std::atan(std::sqrt(36.0 * 36 + 24 * 24) / 100.0));
  EXPECT_NEAR(cameraOf("", 30, 20).fov_y_degrees(), 2 * std::atan(diag * 20 / std::sqrt(30.0 * 30 + 20 * 20)) * deg, 1e-9);
}

TEST(MitsubaImport, CameraFrameFollowsLookatAndRefusesMirrors) {
  v1::Camera c = cameraOf(R"(<float name="fov" value="45"/><transform name="to_world"><lookat origin="1, 2, 3" target="1, 2, 10" up="0, 1, 0"/></transform>)", 8, 8);
  EXPECT_DOUBLE_EQ(c.eye().x(), 1);
  EXPECT_DOUBLE_EQ(c.eye().z(), 3);
  EXPECT_DOUBLE_EQ(c.target().z(), 4);  // eye + unit view direction
  EXPECT_DOUBLE_EQ(c.up().y(), 1);
  try {
    cameraOf(R"(<float name="fov" value="45"/><transform name="to_world"><scale x="-1"/><lookat origin="0, 0, 0" target="0, 0, 1" up="0, 1, 0"/></transform>)", 8, 8);
    FAIL() << "a mirrored camera was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("mirrors the image"), std::string::npos) << e.what();
  }
}

TEST(MitsubaImport, TransformOperationsApplyInDocumentOrder) {
  // translate then scale: the point at the origin ends at (2, 0, 0); scale then translate: (1, 0, 0).
  auto matrixOf = [](const std::string& ops) {
    std::string xml = std::string("<scene version=\"3.0.0\">") + R"(<sensor type="perspective"><float name="fov" value="45"/></sensor>
        <shape type="cube"><transform name="to_world">)" + ops + R"(</transform><emitter type="area"><rgb name="radiance" value="1"/></emitter></shape></scene>)";
    return importText(xml).job.scene().shapes(0).transform();
  };
  v1::Transform a = matrixOf(R"(<translate x="1"/><scale value="2"/>)");
  EXPECT_DOUBLE_EQ(a.matrix(3), 2);
  EXPECT_DOUBLE_EQ(a.matrix(0), 2);
  v1::Transform b = matrixOf(R"(<scale value="2"/><translate x="1"/>)");
  EXPECT_DOUBLE_EQ(b.matrix(3), 1);
  // A quarter turn about z takes x to y, exactly.
  v1::Transform r = matrixOf(R"(<rotate z="1" angle="90"/>)");
  EXPECT_EQ(r.matrix(0), 0);
  EXPECT_EQ(r.matrix(4), 1);
  EXPECT_EQ(r.matrix(1), -1);
}

// ------------------------------------------------------------------------ errors

std::string errorOf(const std::string& xml, const std::string& name = "bad.xml") {
  try {
    importText(xml, name);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}
#define EXPECT_MENTIONS(err, part) EXPECT_NE((err).find(part), std::string::npos) << "error was: " << (err)

TEST(MitsubaImport, BadFilesNameFileLineAndElement) {
  const std::string head = "<scene version=\"3.0.0\">\n<sensor type=\"perspective\"><float name=\"fov\" value=\"45\"/></sensor>\n";
  std::string e = errorOf(head + "<emitter type=\"constant\"/>\n<bsdf type=\"hair\" id=\"h\"/>\n</scene>");
  EXPECT_MENTIONS(e, "bad.xml:4: <bsdf type=\"hair\" id=\"h\">");
  EXPECT_MENTIONS(e, "bsdf type 'hair' is not supported");
  e = errorOf(head + "<emitter type=\"constant\"/>\n\n<shape type=\"obj\"><string name=\"filename\" value=\"nowhere.obj\"/></shape>\n</scene>");
  EXPECT_MENTIONS(e, "bad.xml:5: <shape type=\"obj\">");
  EXPECT_MENTIONS(e, "'nowhere.obj' not found");
  e = errorOf(head + "<emitter type=\"constant\"/>\n<bsdf type=\"twosided\" id=\"a\"><ref id=\"b\"/></bsdf>\n"
                     "<bsdf type=\"twosided\" id=\"b\"><ref id=\"a\"/></bsdf>\n</scene>");
  EXPECT_MENTIONS(e, "cycle");
  EXPECT_MENTIONS(e, "bad.xml:");
  e = errorOf(head + "<emitter type=\"constant\">\n  <rgb name=\"radiance\" value=\"0.5x, 1, 1\"/>\n</emitter>\n</scene>");
  EXPECT_MENTIONS(e, "bad.xml:4: <rgb name=\"radiance\">");
  EXPECT_MENTIONS(e, "malformed number '0.5x'");
  EXPECT_MENTIONS(errorOf("<scene version=\"0.6.0\">\n</scene>"), "bad.xml:1: <scene>: version \"0.6.0\"");
  EXPECT_MENTIONS(errorOf("<scene>\n</scene>"), "missing the version attribute");
  EXPECT_MENTIONS(errorOf("<scene version=\"3.0.0\">\n<shape type=\"cube\">\n</scene>"), "bad.xml:3: malformed XML");
  EXPECT_MENTIONS(errorOf(head + "<emitter type=\"constant\"><float name=\"intensity\" value=\"$missing\"/></emitter></scene>"),
                  "uses $missing, which no <default> defines");
  EXPECT_MENTIONS(errorOf(head + "<emitter type=\"constant\"><float name=\"sparkle\" value=\"1\"/></emitter></scene>"),
                  "property 'sparkle' is not supported");
  EXPECT_MENTIONS(errorOf(head + "<medium type=\"homogeneous\"/></scene>"), "unsupported element <medium>");
  EXPECT_MENTIONS(errorOf(head + "<emitter type=\"constant\"/><shape type=\"cube\"><ref id=\"nobody\"/></shape></scene>"),
                  "no object with id \"nobody\"");
  EXPECT_MENTIONS(errorOf(head + "<emitter type=\"constant\"><spectrum name=\"radiance\" value=\"400:1, 700:2\"/></emitter></scene>"),
                  "invr renders RGB");
  EXPECT_MENTIONS(errorOf(head + "</scene>"), "has no emitter");
  EXPECT_MENTIONS(errorOf("<scene version=\"3.0.0\"><emitter type=\"constant\"/></scene>"), "no <sensor");
}

TEST(MitsubaImport, IgnoredHarmlessPropertiesAreWarnedAbout) {
  MitsubaImport imp = importText(R"(<scene version="3.0.0"><emitter type="constant"/>
    <sensor type="perspective"><float name="fov" value="45"/><film type="hdrfilm"><string name="pixel_format" value="rgba"/>
    <rfilter type="gaussian"/></film></sensor></scene>)");
  std::string all;
  for (const auto& w : imp.warnings) all += w + "\n";
  EXPECT_MENTIONS(all, "pixel_format");
  EXPECT_MENTIONS(all, "gaussian");
  EXPECT_MENTIONS(all, "box filter");
}

// Properties Mitsuba 3 reads that cannot change what it renders (sampling, scheduling, a pinhole's
// focus, shutter times of a static scene) are warned about and ignored, never refused: the scene
// with them renders exactly as the scene without them.
TEST(MitsubaImport, PropertiesThatCannotChangeTheImageAreWarnedNeverRefused) {
  Image env(8, 4, 3);
  for (int y = 0; y < 4; ++y)
    for (int x = 0; x < 8; ++x) env.setRgb(x, y, Rgb(0.1f * float(x + 1), 0.5f, 0.2f));
  writeImage(tmpDir() / "harmless_env.exr", env);
  writeImage(tmpDir() / "harmless_tex.png", env);
  auto scene = [](bool extras) {
    auto x = [&](const std::string& s) { return extras ? s : std::string(); };
    return R"(<scene version="3.0.0">
      <integrator type="direct">)" + x(R"(<integer name="shading_samples" value="4"/><float name="timeout" value="100"/><integer name="block_size" value="16"/>)") + R"(</integrator>
      <sensor type="perspective"><float name="fov" value="45"/>)" + x(R"(<float name="focus_distance" value="3"/><float name="shutter_open" value="0"/><float name="shutter_close" value="0.5"/>)") + R"(
        <transform name="to_world"><lookat origin="0, 0.5, 3" target="0, 0, 0" up="0, 1, 0"/></transform>
        <film type="hdrfilm"><integer name="width" value="24"/><integer name="height" value="16"/><rfilter type="box"/></film></sensor>
      <bsdf type="roughconductor" id="metal"><string name="material" value="Al"/><float name="alpha" value="0.3"/><string name="distribution" value="ggx"/>)" + x(R"(<boolean name="sample_visible" value="false"/>)") + R"(</bsdf>
      <bsdf type="twosided" id="wall">)" + x(R"(<boolean name="allow_transmission" value="false"/>)") + R"(<bsdf type="roughplastic"><float name="alpha" value="0.2"/><string name="distribution" value="ggx"/>)" + x(R"(<boolean name="sample_visible" value="true"/>)") + R"(
        <texture type="bitmap" name="diffuse_reflectance"><string name="filename" value="harmless_tex.png"/>)" + x(R"(<boolean name="accel" value="false"/>)") + R"(</texture></bsdf></bsdf>
      <shape type="rectangle">)" + x(R"(<boolean name="face_normals" value="true"/><float name="silhouette_sampling_weight" value="2"/>)") + R"(<ref id="wall"/>
        <transform name="to_world"><scale value="2"/><translate z="-1"/></transform></shape>
      <shape type="sphere"><float name="radius" value="0.5"/><ref id="metal"/>)" + x(R"(<float name="silhouette_sampling_weight" value="0.5"/>)") + R"(</shape>
      <emitter type="point"><point name="position" x="1" y="1" z="1"/><rgb name="intensity" value="3"/>)" + x(R"(<float name="sampling_weight" value="2"/>)") + R"(</emitter>
      <emitter type="envmap"><string name="filename" value="harmless_env.exr"/>)" + x(R"(<boolean name="mis_compensation" value="true"/>)") + R"(</emitter>
      <emitter type="constant"><rgb name="radiance" value="0.1"/>)" + x(R"(<transform name="to_world"><rotate y="1" angle="30"/></transform>)") + R"(</emitter>
    </scene>)";
  };
  MitsubaImport with = importText(scene(true)), without = importText(scene(false));
  std::string all;
  for (const auto& w : with.warnings) all += w + "\n";
  // (sample_visible is read and dropped silently: a sampling choice of the microfacet BSDFs.)
  for (const char* name : {"shading_samples", "timeout", "block_size", "focus_distance", "shutter_open", "shutter_close",
                           "allow_transmission", "accel", "face_normals", "silhouette_sampling_weight", "sampling_weight", "mis_compensation",
                           "to_world"})
    EXPECT_MENTIONS(all, name);
  v1::JobSpec a = with.job, b = without.job;
  a.mutable_render()->set_spp(2);
  b.mutable_render()->set_spp(2);
  const Image ia = renderJob(a), ib = renderJob(b);
  ASSERT_EQ(ia.data().size(), ib.data().size());
  double sum = 0;
  for (size_t i = 0; i < ia.data().size(); ++i) {
    EXPECT_EQ(ia.data()[i], ib.data()[i]) << "value " << i;
    sum += ia.data()[i];
  }
  EXPECT_GT(sum, 0.0);
  // Where such a property would change Mitsuba's image, it is refused, saying why.
  const std::string head = R"(<scene version="3.0.0"><sensor type="perspective"><float name="fov" value="45"/></sensor>)";
  EXPECT_MENTIONS(errorOf(head + R"(<emitter type="point"><float name="sampling_weight" value="0"/></emitter></scene>)"),
                  "sampling_weight 0 removes this light");
  EXPECT_MENTIONS(errorOf(head + R"(<emitter type="constant"/><integrator type="direct"><integer name="bsdf_samples" value="0"/></integrator></scene>)"),
                  "bsdf_samples = 0");
  EXPECT_MENTIONS(errorOf(head + R"(<emitter type="constant"/><shape type="sphere"><boolean name="face_normals" value="true"/></shape></scene>)"),
                  "property 'face_normals' is not supported");
}

// The projective integrators Mitsuba's shape scenes name: direct_projective is direct
// illumination, prb_projective a path tracer; their boundary sampling options are warned about and
// ignored (invr's boundary terms do that work). Several sensors become several views.
TEST(MitsubaImport, ProjectiveIntegratorsImportWithTheirSamplingOptionsIgnored) {
  const std::string sensor = R"(<sensor type="perspective"><float name="fov" value="45"/>
    <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="8"/><rfilter type="box"/></film></sensor>)";
  auto warnings = [](const MitsubaImport& imp) {
    std::string all;
    for (const auto& w : imp.warnings) all += w + "\n";
    return all;
  };
  MitsubaImport direct = importText(R"(<scene version="3.0.0"><emitter type="constant"/>
    <integrator type="direct_projective"><integer name="sppc" value="32"/><integer name="sppp" value="32"/><integer name="sppi" value="0"/>
    <string name="guiding" value="none"/></integrator>)" + sensor + sensor + "</scene>");
  EXPECT_EQ(direct.job.render().max_depth(), 1);
  EXPECT_EQ(direct.job.scene().views_size(), 2);
  EXPECT_MENTIONS(warnings(direct), "sppc, sppp, sppi, guiding: ignored");
  MitsubaImport prb = importText(R"(<scene version="3.0.0"><emitter type="constant"/>
    <integrator type="prb_projective"><integer name="max_depth" value="4"/><integer name="sppi" value="64"/>
    <boolean name="guiding_proj" value="false"/></integrator>)" + sensor + "</scene>");
  EXPECT_EQ(prb.job.render().max_depth(), 3);
  EXPECT_MENTIONS(warnings(prb), "sppi, guiding_proj: ignored");
  EXPECT_MENTIONS(errorOf(R"(<scene version="3.0.0"><emitter type="constant"/><integrator type="volpath"/>)" + sensor + "</scene>"),
                  "direct_projective");
}

TEST(MitsubaImport, LookatWithoutUpTakesMitsubasFrame) {
  // Looking down -z, Mitsuba's orthonormal frame (Duff et al.) puts up along +x.
  v1::Camera c = cameraOf(R"(<float name="fov" value="45"/><transform name="to_world"><lookat origin="0, 0, 5" target="0, 0, 0"/></transform>)", 8, 8);
  EXPECT_DOUBLE_EQ(c.up().x(), 1);
  EXPECT_DOUBLE_EQ(c.up().y(), 0);
  EXPECT_DOUBLE_EQ(c.up().z(), 0);
  EXPECT_MENTIONS(errorOf(R"(<scene version="3.0.0"><emitter type="constant"/><sensor type="perspective"><float name="fov" value="45"/>
      <transform name="to_world"><scale value="2"/><lookat origin="0, 0, 5" target="0, 0, 0" up="0, 1, 0"/></transform></sensor></scene>)"),
                  "must be a rotation and translation");
}

TEST(MitsubaImport, NamesSubstitutionsAndDefaultsFollowMitsuba) {
  const std::string camera = R"(<sensor type="perspective"><float name="fov" value="45"/><film type="hdrfilm"><rfilter type="box"/></film></sensor>)";
  Image tex(2, 2, 3);
  writeImage(tmpDir() / "wood_diffuse.exr", tex);
  MitsubaImport imp = importText(R"(<scene version="3.0.0"><default name="name" value="wood"/>)" + camera + R"(
      <bsdf type="diffuse" id="inner"><texture type="bitmap" name="reflectance"><string name="filename" value="$name_diffuse.exr"/>
        <boolean name="raw" value="true"/></texture></bsdf>
      <bsdf type="twosided" id="outer"><ref name="bsdf" id="inner"/></bsdf>
      <bsdf type="diffuse" id="bsdf_1"/>
      <bsdf type="diffuse" id="spare"/>
      <shape type="rectangle"><ref name="bsdf" id="outer"/></shape>
      <shape type="cube"><bsdf type="diffuse"/></shape>
      <shape type="cube" id="cube_2"><ref id="bsdf_1"/></shape>
      <shape type="rectangle" id="lamp"><emitter type="area"/></shape></scene>)");
  const auto& sc = imp.job.scene();
  ASSERT_EQ(sc.materials_size(), 4);
  EXPECT_EQ(sc.materials(0).name(), "outer");
  EXPECT_EQ(sc.materials(0).diffuse().albedo().image().path(), "wood_diffuse.exr");  // $name then "_diffuse"
  EXPECT_FALSE(sc.materials(0).diffuse().albedo().srgb());                          // raw=true
  ASSERT_EQ(sc.materials(0).aliases_size(), 1);
  EXPECT_EQ(sc.materials(0).aliases(0), "inner");
  // Generated names step over ids: "cube_2" and "bsdf_1" are ids here.
  EXPECT_EQ(sc.shapes(0).name(), "rectangle_1");
  EXPECT_EQ(sc.shapes(1).name(), "cube_3");
  EXPECT_EQ(sc.materials(1).name(), "bsdf_4");
  EXPECT_EQ(sc.materials(2).name(), "bsdf_1");
  EXPECT_DOUBLE_EQ(sc.lights(0).area().radiance().r(), 1.0);  // Mitsuba's default radiance
  std::string all;
  for (const auto& w : imp.warnings) all += w + "\n";
  EXPECT_MENTIONS(all, "bsdf \"spare\" is not used");
  EXPECT_EQ(all.find("\"inner\" is not used"), std::string::npos) << all;
  // The wrapped bsdf's Mitsuba name reaches the material that renders it.
  AssetResolver assets;
  assets.baseDir = tmpDir();
  auto scene = buildJobScene(imp.job, assets, SceneUse::Validate);
  EXPECT_EQ(invrParameterName(*scene, "inner.reflectance.data"), "materials/outer/albedo");
  // An unused bsdf is still checked.
  EXPECT_MENTIONS(errorOf(R"(<scene version="3.0.0"><emitter type="constant"/>)" + camera + R"(<bsdf type="velvet" id="unused"/></scene>)"),
                  "bsdf type 'velvet' is not supported");
}

}  // namespace
}  // namespace invr
