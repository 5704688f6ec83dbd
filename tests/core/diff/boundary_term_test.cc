// The boundary-term family: each term parses its own options from its message under its
// registered name, and takes a random stream that no other purpose has.
#include "core/diff/boundary_term.h"

#include <gtest/gtest.h>
#include <google/protobuf/util/json_util.h>

#include <set>
#include <stdexcept>
#include <string>

#include "core/diff/area_shadow_boundary.h"
#include "core/diff/edge_reservoir_boundary.h"
#include "core/diff/environment_shadow_boundary.h"
#include "core/diff/gradient_engine.h"
#include "core/diff/gradient_options.h"
#include "core/diff/pixel_sampler.h"
#include "core/diff/primary_boundary.h"
#include "core/error.h"
#include "core/job/problem.h"
#include "core/optim/image_error.h"
#include "test_util.h"

namespace invr {
namespace {

namespace v1 = invr::v1;

v1::BoundarySpec specFrom(const std::string& json) {
  v1::BoundarySpec spec;
  const auto status = google::protobuf::util::JsonStringToMessage(json, &spec);
  EXPECT_TRUE(status.ok()) << status.ToString();
  return spec;
}

std::string parseError(const std::string& json) {
  try {
    parseBoundaryOptions(specFrom(json));
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

// The messages under BoundarySpec.terms are the registered terms, one each, by name: a term
// without a message could not be given options, a message without a term would be ignored.
TEST(BoundaryTerms, EachRegisteredTermHasTheMessageOfItsName) {
  std::set<std::string> fields, names;
  const google::protobuf::Descriptor* d = v1::BoundaryTermSpecs::descriptor();
  for (int i = 0; i < d->field_count(); ++i) fields.insert(d->field(i)->name());
  for (const BoundaryTermKind* k : boundaryTermKinds()) names.insert(k->name);
  EXPECT_EQ(fields, names);
  // And every term's message has the shared fields parseSharedTermFields reads.
  for (int i = 0; i < d->field_count(); ++i) {
    const google::protobuf::Descriptor* m = d->field(i)->message_type();
    ASSERT_NE(m->FindFieldByName("enabled"), nullptr) << m->name();
    ASSERT_NE(m->FindFieldByName("samples"), nullptr) << m->name();
  }
}

TEST(BoundaryTerms, EachTermReadsItsOwnMessage) {
  const BoundaryOptions none = parseBoundaryOptions(specFrom("{}"));
  EXPECT_EQ(none.termOr<EdgeFirstAreaShadowOptions>().edgeNeighbours, 0);
  EXPECT_TRUE(none.termOr<EdgeFirstAreaShadowOptions>().edgeImportance);
  EXPECT_TRUE(none.termOr<PrimaryBoundaryOptions>().terminators);
  EXPECT_EQ(none.samplesFor(PrimaryBoundaryOptions::kTerm, 64, 64), 1024);

  const BoundaryOptions o = parseBoundaryOptions(specFrom(R"({"samples": 300, "light_points": 8, "edge_neighbours": 2, "terms": {
      "primary": {"samples": 700, "terminators": false},
      "delta_shadows": {"enabled": false},
      "area_shadows_edge_first": {"edge_neighbours": 5, "edge_importance": false},
      "area_shadows_light_points": {"light_points": 32},
      "environment_shadows": {"directions": 4}}})"));
  EXPECT_EQ(o.samplesFor(PrimaryBoundaryOptions::kTerm, 64, 64), 700);
  EXPECT_EQ(o.samplesFor("delta_shadows", 64, 64), 300);
  EXPECT_FALSE(o.termOr<PrimaryBoundaryOptions>().terminators);
  EXPECT_FALSE(o.enabled("delta_shadows"));
  EXPECT_TRUE(o.enabled(PrimaryBoundaryOptions::kTerm));
  EXPECT_EQ(o.termOr<EdgeFirstAreaShadowOptions>().edgeNeighbours, 5);  // its own message over the shared alias
  EXPECT_FALSE(o.termOr<EdgeFirstAreaShadowOptions>().edgeImportance);
  EXPECT_EQ(o.termOr<LightPointsAreaShadowOptions>().lightPointsOf(o), 32);
  EXPECT_EQ(o.termOr<EnvironmentShadowOptions>().directionsOf(o), 4);

  // The shared fields stay the job-wide values of the terms that do not override them.
  const BoundaryOptions shared = parseBoundaryOptions(specFrom(R"({"light_points": 8, "edge_neighbours": 2, "edge_importance": false})"));
  EXPECT_EQ(shared.termOr<EdgeFirstAreaShadowOptions>().edgeNeighbours, 2);
  EXPECT_FALSE(shared.termOr<EdgeFirstAreaShadowOptions>().edgeImportance);
  EXPECT_EQ(shared.termOr<LightPointsAreaShadowOptions>().lightPointsOf(shared), 8);
  EXPECT_EQ(shared.termOr<EnvironmentShadowOptions>().directionsOf(shared), 8);
}

TEST(BoundaryTerms, MistakesNameTheTermsField) {
  EXPECT_NE(parseError(R"({"terms": {"primary": {"samples": -1}}})").find("optimization.boundary.terms.primary.samples"), std::string::npos);
  EXPECT_NE(parseError(R"({"terms": {"delta_shadows": {"samples": 20000000}}})").find("optimization.boundary.terms.delta_shadows.samples"),
            std::string::npos);
  EXPECT_NE(parseError(R"({"terms": {"area_shadows_edge_first": {"edge_neighbours": 9}}})")
                .find("optimization.boundary.terms.area_shadows_edge_first.edge_neighbours"),
            std::string::npos);
  EXPECT_NE(parseError(R"({"edge_neighbours": -1})").find("optimization.boundary.edge_neighbours"), std::string::npos);
  EXPECT_EQ(parseError(R"({"terms": {"primary": {}}})"), "");
}

// A copied GradientOptions changes alone: ablations and tests copy a job's options and switch a
// term's option off.
TEST(BoundaryTerms, CopiedOptionsChangeAlone) {
  GradientOptions a;
  a.boundary = parseBoundaryOptions(specFrom(R"({"terms": {"area_shadows_edge_first": {"edge_neighbours": 3}}})"));
  GradientOptions b = a;
  b.boundary.term<EdgeFirstAreaShadowOptions>().edgeNeighbours = 7;
  b.boundary.term<PrimaryBoundaryOptions>().terminators = false;
  EXPECT_EQ(a.boundary.termOr<EdgeFirstAreaShadowOptions>().edgeNeighbours, 3);
  EXPECT_TRUE(a.boundary.termOr<PrimaryBoundaryOptions>().terminators);
  EXPECT_EQ(b.boundary.termOr<EdgeFirstAreaShadowOptions>().edgeNeighbours, 7);
}

// A term switched off in its message is not run, whatever the scene.
TEST(BoundaryTerms, ADisabledTermDoesNotRun) {
  auto scene = test::sceneFromJson(R"({
    "materials": [{"name": "grey", "diffuse": {}}],
    "shapes": [{"name": "floor", "quad": {}, "material": "grey", "transform": {"scale": {"x": 5, "y": 5, "z": 1}}},
               {"name": "card", "quad": {}, "material": "grey", "transform": {"scale": {"x": 0.25, "y": 0.25, "z": 1}, "translate": {"z": 2}}}],
    "lights": [{"name": "bulb", "point": {"position": {"x": 2, "z": 4}, "intensity": {"r": 10, "g": 10, "b": 10}}}],
    "views": [{"eye": {"z": 6}, "target": {}, "fov_y_degrees": 60}], "film": {"width": 16, "height": 16}})");
  ParameterRegistry reg;
  reg.add(*scene, "shapes/card/translation");
  auto names = [&](const std::string& json) {
    GradientOptions o;
    o.boundary = parseBoundaryOptions(specFrom(json));
    std::vector<std::string> out;
    for (const BoundaryTermKind* k : boundaryTermsFor(*scene, reg, o)) out.push_back(k->name);
    return out;
  };
  EXPECT_EQ(names("{}"), (std::vector<std::string>{"primary", "delta_shadows"}));
  EXPECT_EQ(names(R"({"terms": {"delta_shadows": {"enabled": false}}})"), (std::vector<std::string>{"primary"}));
  EXPECT_EQ(names(R"({"terms": {"primary": {"enabled": false}}})"), (std::vector<std::string>{"delta_shadows"}));
}

// ---- random streams ---------------------------------------------------------------------------

TEST(BoundaryTerms, StreamsAreTheirOwnAndApartFromTheEngines) {
  const std::vector<StreamId> engine = {kPrimalStream,        kDerivativeStream, kStage1PrimalStream, kStage1DerivativeStream,
                                        kTargetStream,        kPixelBatchStream, kViewBatchStream,    kFinalRenderStream,
                                        kImageErrorStream,    kVarianceStream,   kVarianceMapStream};
  std::set<uint64_t> seen;
  for (StreamId s : engine) {
    EXPECT_TRUE(seen.insert(s.value).second) << "engine stream " << s.value << " twice";
    EXPECT_GE(s.value, 1u);
    EXPECT_LE(s.value, kLastEngineStream);
  }
  const auto& kinds = boundaryTermKinds();
  for (const BoundaryTermKind* k : kinds) {
    EXPECT_GT(k->stream().value, kLastEngineStream) << k->name;
    for (const BoundaryTermKind* other : kinds) {
      if (other != k && other->stream() == k->stream()) {
        EXPECT_EQ(other->samples, k->samples) << k->name << " and " << other->name << " share a stream but sample different discontinuities";
      }
    }
  }
}

TEST(BoundaryTerms, ANamedStreamComesFromTheName) {
  EXPECT_EQ(StreamId::named("my_shadows"), StreamId::named("my_shadows"));
  EXPECT_NE(StreamId::named("my_shadows"), StreamId::named("my_shadow"));
  EXPECT_GT(StreamId::named("a").value, kLastEngineStream);
  BoundaryTermKind k;
  k.name = "my_shadows";
  EXPECT_EQ(k.stream(), StreamId::named("my_shadows"));
  k.pinnedStream = StreamId{14};
  EXPECT_EQ(k.stream().value, 14u);
}

// Registration refuses what would make two purposes share numbers, before anything is added.
TEST(BoundaryTerms, RegistrationRefusesATakenStream) {
  const size_t before = boundaryTermKinds().size();
  auto kind = [](const std::string& name, int order) {
    BoundaryTermKind k;
    k.name = name;
    k.order = order;
    k.samples = {Discontinuity::ContactCurves};
    k.parse = [](const v1::BoundarySpec&) { return std::unique_ptr<BoundaryTermOptions>(); };
    return k;
  };
  BoundaryTermKind taken = kind("contacts_a", 901);
  taken.pinnedStream = boundaryTermKinds().front()->stream();  // the primary term's, which samples mesh edges
  EXPECT_THROW(RegisterBoundaryTerm{taken}, std::logic_error);
  BoundaryTermKind engines = kind("contacts_b", 902);
  engines.pinnedStream = kPrimalStream;
  EXPECT_THROW(RegisterBoundaryTerm{engines}, std::logic_error);
  BoundaryTermKind unparsed = kind("contacts_c", 903);
  unparsed.parse = {};
  EXPECT_THROW(RegisterBoundaryTerm{unparsed}, std::logic_error);
  BoundaryTermKind sameName = kind("primary", 904);
  EXPECT_THROW(RegisterBoundaryTerm{sameName}, std::logic_error);
  EXPECT_EQ(boundaryTermKinds().size(), before);
}

}  // namespace
}  // namespace invr
