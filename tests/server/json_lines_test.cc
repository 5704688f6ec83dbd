// The JSON that --json and progress.jsonl print: numbers as numbers, non-finite as null, enums by
// name, scalar fields always present, and protobuf's parser reads it back.
#include "proto/wire/json_lines.h"

#include <google/protobuf/util/json_util.h>
#include <gtest/gtest.h>

#include <cmath>

#include "invr/v1/service.pb.h"

namespace invr::wire {
namespace {

TEST(JsonLines, NumbersAreNumbersAndNonFiniteIsNull) {
  v1::ProgressEvent e;
  e.set_sequence(12345678901234ull);
  auto* s = e.mutable_step();
  s->set_step(3);
  s->set_loss(std::nan(""));
  s->set_image_loss(0.25);
  s->mutable_stats()->mutable_rays()->set_camera(7);
  auto* p = s->add_parameters();
  p->set_name("materials/red/albedo");
  p->add_values(0.5);
  const std::string line = jsonLine(e);
  EXPECT_NE(line.find("\"sequence\":12345678901234"), std::string::npos) << line;
  EXPECT_NE(line.find("\"step\":3,"), std::string::npos) << line;
  EXPECT_NE(line.find("\"loss\":null"), std::string::npos) << line;
  EXPECT_NE(line.find("\"camera\":7"), std::string::npos) << line;
  EXPECT_NE(line.find("\"shadow\":0"), std::string::npos) << line;  // zero counters too
  EXPECT_NE(line.find("\"parameters\":[{\"name\":\"materials/red/albedo\",\"values\":[0.5]}]"), std::string::npos) << line;
  EXPECT_EQ(line.find('\n'), std::string::npos);
  v1::ProgressEvent back;
  ASSERT_TRUE(google::protobuf::util::JsonStringToMessage(line, &back).ok()) << line;
  EXPECT_EQ(back.sequence(), e.sequence());
  EXPECT_EQ(back.step().image_loss(), 0.25);
  EXPECT_EQ(back.step().loss(), 0.0);  // null reads back as the default
}

TEST(JsonLines, EnumsByNameAndUnsetMessagesLeftOut) {
  v1::JobStatus st;
  st.set_state(v1::SUCCEEDED);
  const std::string line = jsonLine(st);
  EXPECT_NE(line.find("\"state\":\"SUCCEEDED\""), std::string::npos) << line;
  v1::ProgressEvent e;
  e.set_message("queued");
  const std::string ev = jsonLine(e);
  EXPECT_EQ(ev.find("\"step\""), std::string::npos) << ev;  // the oneof's other members
  EXPECT_NE(ev.find("\"message\":\"queued\""), std::string::npos) << ev;
}

}  // namespace
}  // namespace invr::wire
