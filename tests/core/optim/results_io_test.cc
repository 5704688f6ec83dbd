#include "core/optim/results_io.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

#include "core/io/mesh_io.h"
#include "test_util.h"

namespace invr {
namespace {

namespace fs = std::filesystem;

// A material whose name has a quote, a backslash and a newline (escaped here as JSON), a
// textured material and a light.
constexpr const char* kScene = R"({
  "materials": [{"name": "say \"hi\" C:\\dir\nnext", "diffuse": {"albedo": {"constant": {"r": 0.5, "g": 0.5, "b": 0.5}}}},
                {"name": "t", "diffuse": {"albedo": {"procedural": {"pattern": "checker", "width": 4}, "scale": 0.5}}}],
  "shapes": [{"name": "q", "material": "say \"hi\" C:\\dir\nnext", "quad": {}}, {"name": "p", "material": "t", "quad": {}}],
  "lights": [{"name": "l", "point": {"position": {"z": 2}, "intensity": {"r": 1, "g": 1, "b": 1}}}],
  "views": [{"eye": {"z": 3}, "target": {}}]
})";

struct TempDir {
  fs::path path;
  TempDir() {
    path = fs::temp_directory_path() /
           ("invr_results_io_" + std::to_string(::getpid()) + "_" + ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(path);
    fs::create_directories(path);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
};

std::string readText(const fs::path& file) {
  std::ifstream in(file);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

nlohmann::json readJson(const fs::path& file) { return nlohmann::json::parse(readText(file)); }  // throws on invalid JSON

TEST(ResultsIo, ParameterNamesWithQuotesBackslashesAndNewlinesRoundTrip) {
  const std::string odd = "materials/say \"hi\" C:\\dir\nnext/albedo";
  auto scene = test::sceneFromJson(kScene);
  ParameterRegistry reg;
  reg.add(*scene, odd);
  reg.add(*scene, "lights/l/intensity");
  std::vector<float> theta = reg.read(*scene);
  ASSERT_EQ(theta.size(), 6u);
  theta = {0.1f, 0.123456789f, 0.75f, 2.5f, 1e-7f, 12345.6f};

  TempDir dir;
  auto files = writeParameters(dir.path, reg, theta, *scene);
  ASSERT_EQ(files, std::vector<std::string>{"parameters.json"});
  nlohmann::json js;
  ASSERT_NO_THROW(js = readJson(dir.path / "parameters.json"));
  ASSERT_TRUE(js.is_object());
  ASSERT_EQ(js.size(), 2u);
  ASSERT_TRUE(js.contains(odd)) << js.dump();
  ASSERT_TRUE(js.contains("lights/l/intensity")) << js.dump();
  const auto& a = js.at(odd);
  const auto& l = js.at("lights/l/intensity");
  ASSERT_TRUE(a.is_array() && a.size() == 3u) << a.dump();
  ASSERT_TRUE(l.is_array() && l.size() == 3u) << l.dump();
  // Values are written with 6 significant digits (as before): these read back as the same floats.
  for (size_t k = 0; k < 3; ++k) {
    ASSERT_TRUE(a[k].is_number() && l[k].is_number()) << k;
    if (k != 1) {
      EXPECT_EQ(a[k].get<float>(), theta[k]) << k;
    }
    EXPECT_EQ(l[k].get<float>(), theta[3 + k]) << k;
  }
  EXPECT_NEAR(a[1].get<double>(), 0.123457, 1e-12);
  // Written in the registry's order.
  std::string text = readText(dir.path / "parameters.json");
  EXPECT_LT(text.find("materials/say"), text.find("lights/l/intensity")) << text;
}

TEST(ResultsIo, TexturesAreNamedByTheirImageFile) {
  auto scene = test::sceneFromJson(kScene);
  ParameterRegistry reg;
  reg.add(*scene, "materials/t/albedo");
  std::vector<float> theta = reg.read(*scene);
  TempDir dir;
  auto files = writeParameters(dir.path, reg, theta, *scene);
  ASSERT_EQ(files, (std::vector<std::string>{"parameters.json", "materials_t_albedo.exr"}));
  EXPECT_GT(fs::file_size(dir.path / "materials_t_albedo.exr"), 0u);
  nlohmann::json js = readJson(dir.path / "parameters.json");
  EXPECT_EQ(js, nlohmann::json::parse(R"({"materials/t/albedo": {"texture": "materials_t_albedo.exr", "width": 4, "height": 4}})"));
}

// A vertex parameter's mesh is written as mesh_<shape>.ply (binary), which parameters.json names;
// it reads back (through the mesh loader users' meshes go through) with the values written.
TEST(ResultsIo, VertexParametersAreWrittenAsPlyMeshes) {
  auto scene = test::sceneFromJson(kScene);
  ParameterRegistry reg;
  reg.add(*scene, "shapes/q/vertices");
  std::vector<float> theta = reg.read(*scene);
  ASSERT_EQ(theta.size(), 12u);
  for (size_t i = 0; i < theta.size(); ++i) theta[i] += 0.01f * float(i);
  TempDir dir;
  auto files = writeParameters(dir.path, reg, theta, *scene);
  ASSERT_EQ(files, (std::vector<std::string>{"parameters.json", "mesh_q.ply"}));
  EXPECT_EQ(readJson(dir.path / "parameters.json"),
            nlohmann::json::parse(R"({"shapes/q/vertices": {"mesh": "mesh_q.ply", "vertices": 4, "triangles": 2}})"));
  const TriangleMesh back = loadMesh(dir.path / "mesh_q.ply");
  ASSERT_EQ(back.positions.size(), 4u);
  ASSERT_EQ(back.triangleCount(), 2u);
  for (size_t v = 0; v < 4; ++v)
    for (int c = 0; c < 3; ++c) EXPECT_EQ(back.positions[v][c], theta[3 * v + size_t(c)]) << v << " " << c;
  EXPECT_EQ(back.indices, scene->meshes[0].indices);
}

TEST(ResultsIo, NonFiniteValuesStayValidJson) {
  auto scene = test::sceneFromJson(kScene);
  ParameterRegistry reg;
  reg.add(*scene, "lights/l/intensity");
  std::vector<float> theta = {std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity(), 1.f};
  TempDir dir;
  writeParameters(dir.path, reg, theta, *scene);
  nlohmann::json js;
  ASSERT_NO_THROW(js = readJson(dir.path / "parameters.json"));
  EXPECT_EQ(js.at("lights/l/intensity"), nlohmann::json::parse("[null, null, 1.0]"));
}

// Each column once (the statistics' own loss is the row's loss column), every row as wide as the
// header, and a boundary term's columns present from the first row that has it (blank before).
TEST(ResultsIo, ConvergenceCsvHasEachColumnOnceAndRowsAsWideAsTheHeader) {
  TempDir dir;
  ConvergenceCsv csv(dir.path / "convergence.csv");
  invr::v1::GradientStats a;
  a.set_loss(0.25);
  a.set_seconds_primal(1.5);
  a.mutable_rays()->set_camera(7);
  ConvergenceRow first{"restir", 1, 2.0, 0.25, 0.5, 0.125, a};
  invr::v1::GradientStats b = a;
  (*b.mutable_boundary())["primary"].set_samples(3072);
  ConvergenceRow second{"restir", 2, 4.0, 0.125, 0.25, 0.0625, b};
  csv.add(first);
  csv.add(second);
  csv.write();
  std::stringstream text(readText(dir.path / "convergence.csv"));
  auto cellsOf = [](const std::string& line) {
    std::vector<std::string> cells;
    std::stringstream ss(line);
    std::string c;
    while (std::getline(ss, c, ',')) cells.push_back(c);
    if (!line.empty() && line.back() == ',') cells.push_back("");
    return cells;
  };
  std::string line;
  ASSERT_TRUE(std::getline(text, line));
  std::vector<std::string> header = cellsOf(line);
  ASSERT_GE(header.size(), 6u);
  EXPECT_EQ(std::vector<std::string>(header.begin(), header.begin() + 6),
            (std::vector<std::string>{"method", "step", "seconds", "loss", "param_error", "image_error"}));
  std::map<std::string, size_t> column;
  for (size_t i = 0; i < header.size(); ++i) EXPECT_TRUE(column.emplace(header[i], i).second) << "column '" << header[i] << "' twice";
  ASSERT_TRUE(column.count("seconds_primal") && column.count("rays.camera") && column.count("boundary.primary.samples"));
  std::vector<std::vector<std::string>> rows;
  while (std::getline(text, line)) rows.push_back(cellsOf(line));
  ASSERT_EQ(rows.size(), 2u);
  for (const auto& r : rows) ASSERT_EQ(r.size(), header.size());
  EXPECT_EQ(rows[0][column["loss"]], "0.25");
  EXPECT_EQ(rows[0][column["seconds_primal"]], "1.5");
  EXPECT_EQ(rows[0][column["rays.camera"]], "7");
  EXPECT_EQ(rows[0][column["boundary.primary.samples"]], "");
  EXPECT_EQ(rows[1][column["boundary.primary.samples"]], "3072");
  EXPECT_EQ(rows[1][column["image_error"]], "0.0625");
}

}  // namespace
}  // namespace invr
