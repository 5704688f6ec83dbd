// Job JSON errors name the field (path and line:column) and never crash.
#include "core/io/job_io.h"

#include <gtest/gtest.h>

#include "core/error.h"

namespace invr {
namespace {

std::string errorOf(const std::string& json) {
  try {
    parseJobJson(json, "job.json");
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

bool contains(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

TEST(JobJson, ValidJobRoundTrips) {
  auto job = parseJobJson(R"({"name": "a", "zoo": "cornell", "render": {"spp": 4, "estimator": "ESTIMATOR_RIS"}})");
  EXPECT_EQ(job.zoo(), "cornell");
  EXPECT_EQ(job.render().spp(), 4);
  auto again = parseJobJson(jobToJson(job));
  EXPECT_EQ(again.SerializeAsString(), job.SerializeAsString());
}

TEST(JobJson, UnknownFieldNamesPathAndLine) {
  std::string e = errorOf("{\n  \"zoo\": \"cornell\",\n  \"render\": {\n    \"spq\": 4\n  }\n}");
  EXPECT_TRUE(contains(e, "render.spq: unknown field")) << e;
  EXPECT_TRUE(contains(e, "job.json:4:")) << e;
}

TEST(JobJson, WrongTypeNamesField) {
  std::string e = errorOf(R"({"render": {"spp": "many"}})");
  EXPECT_TRUE(contains(e, "render.spp")) << e;
  e = errorOf(R"({"render": {"estimator": "ESTIMATOR_MAGIC"}})");
  EXPECT_TRUE(contains(e, "render.estimator")) << e;
}

TEST(JobJson, NestedUnknownFieldNamesIndexedPath) {
  std::string e = errorOf(R"({"scene": {"lights": [{"name": "a"}, {"name": "b", "colour": 1}]}})");
  EXPECT_TRUE(contains(e, "scene.lights[1].colour: unknown field")) << e;
}

TEST(JobJson, MalformedJsonGivesLocation) {
  std::string e = errorOf("{\n  \"zoo\": \"cornell\",,\n}");
  EXPECT_TRUE(contains(e, "job.json:2:")) << e;
  EXPECT_FALSE(errorOf("").empty());
  EXPECT_FALSE(errorOf("[1, 2]").empty());
}

TEST(JobJson, EnumsInTheirShortFormMeanTheProtoValues) {
  auto job = parseJobJson(
      R"({"zoo": "cornell", "render": {"estimator": "ris"}, "optimization": {"method": "Restir", "boundary": {"area_sampling": "light-points"}}})");
  EXPECT_EQ(job.render().estimator(), v1::ESTIMATOR_RIS);
  EXPECT_EQ(job.optimization().method(), v1::METHOD_RESTIR);
  EXPECT_EQ(job.optimization().boundary().area_sampling(), v1::AREA_SAMPLING_LIGHT_POINTS);
  EXPECT_EQ(parseJobJson(R"({"zoo": "cornell", "optimization": {"method": "METHOD_PT"}})").optimization().method(), v1::METHOD_PT);
}

TEST(JobJson, MistakesAreNamedInTheUsersWords) {
  std::string e = errorOf("{\"zoo\": \"cornell\",\n \"optimization\": {\"method\": \"restri\"}}");
  EXPECT_TRUE(contains(e, "job.json:2:")) << e;
  EXPECT_TRUE(contains(e, "optimization.method: 'restri' is not a valid value; use one of: pt, ris, restir; did you mean 'restir'?")) << e;
  e = errorOf(R"({"zoo": "cornell", "optimization": {"parameters": [{"name": "x", "initial": [1, 2]}]}})");
  EXPECT_TRUE(contains(e, "optimization.parameters[0].initial: expects a single number, not a list; a list goes in 'initial_values'")) << e;
  e = errorOf(R"({"zoo": "cornell", "optimization": {"parameters": {"name": "x"}}})");
  EXPECT_TRUE(contains(e, "optimization.parameters: expects a list")) << e;
  e = errorOf(R"({"zoo": "cornell", "render": {"spq": 4}})");
  EXPECT_TRUE(contains(e, "render.spq: unknown field; did you mean 'spp'?")) << e;
  e = errorOf("{\n  \"zoo\": \"cornell\",\n  \"render\": {\n");
  EXPECT_TRUE(contains(e, "job.json:4:1: JSON syntax error")) << e;
  e = errorOf(R"({"zoo": "cornell", "render": {"spp": 2e308}})");  // found by fuzz_job_json
  EXPECT_TRUE(contains(e, "JSON number out of range")) << e;
}

TEST(JobJson, NegativeSppNamesField) {
  std::string e = errorOf(R"({"zoo": "cornell", "render": {"spp": -3}})");
  EXPECT_TRUE(contains(e, "render.spp")) << e;
  EXPECT_TRUE(contains(e, "-3")) << e;
}

TEST(JobJson, MissingFileIsAnError) {
  EXPECT_THROW(loadJobFile("/nonexistent/job.json"), InputError);
}

TEST(JobJson, UnknownEnumNumbersAreRefusedNamingTheField) {
  auto e = errorOf(R"({"zoo": "cornell", "optimization": {"method": 99}})");
  EXPECT_TRUE(contains(e, "optimization.method: unknown value 99 (use one of METHOD_PT, METHOD_RIS, METHOD_RESTIR)")) << e;
  e = errorOf(R"({"zoo": "cornell", "render": {"estimator": 42}})");
  EXPECT_TRUE(contains(e, "render.estimator: unknown value 42")) << e;
  EXPECT_EQ(errorOf(R"({"zoo": "cornell", "optimization": {"method": 3}})"), "");
}

TEST(JobJson, StringsAndRepeatedFieldsAreBounded) {
  auto e = errorOf(R"({"zoo": "cornell", "name": ")" + std::string(300, 'n') + R"("})");
  EXPECT_TRUE(contains(e, "name: 300 bytes long (limit 256)")) << e;
  e = errorOf(R"({"scene": {"shapes": [{"name": "a", "mesh": {"path": ")" + std::string(5000, 'p') + R"("}}]}})");
  EXPECT_TRUE(contains(e, "scene.shapes[0].mesh.path: 5000 bytes long (limit 4096)")) << e;
  std::string many = R"({"zoo": "cornell", "optimization": {"parameters": [)";
  for (int i = 0; i < 65537; ++i) many += std::string(i ? "," : "") + "{}";
  e = errorOf(many + "]}}");
  EXPECT_TRUE(contains(e, "optimization.parameters: 65537 entries (limit 65536)")) << e;
}

}  // namespace
}  // namespace invr
