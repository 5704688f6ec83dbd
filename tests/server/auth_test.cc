// Client token files: names, the token alone, comments, and the errors a user can make.
#include "server/auth.h"

#include <gtest/gtest.h>

#include <fstream>

#include "core/error.h"

namespace invr::server {
namespace {

std::filesystem::path write(const std::string& name, const std::string& text) {
  auto p = std::filesystem::temp_directory_path() / ("invr_auth_test_" + name);
  std::ofstream(p) << text;
  return p;
}

TEST(ClientTokenFile, NamesAndTheTokenAlone) {
  auto t = readClientTokenFile(write("ok", "# who token\nalice s3cret-a\n\n  bob   s3cret-b  \n"));
  ASSERT_EQ(t.size(), 2u);
  EXPECT_EQ(t[0].name, "alice");
  EXPECT_EQ(t[0].token, "s3cret-a");
  EXPECT_EQ(t[1].name, "bob");
  EXPECT_EQ(t[1].token, "s3cret-b");
  auto one = readClientTokenFile(write("one", "just-a-token\n"));
  ASSERT_EQ(one.size(), 1u);
  EXPECT_EQ(one[0].name, "client");
  EXPECT_EQ(one[0].token, "just-a-token");
}

TEST(ClientTokenFile, MistakesAreNamed) {
  auto message = [](const std::string& name, const std::string& text) {
    try {
      readClientTokenFile(write(name, text));
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(message("empty", "# nothing\n\n").find("no token in it"), std::string::npos);
  EXPECT_NE(message("three", "a b c\n").find("line 1: more than two fields"), std::string::npos);
  EXPECT_NE(message("dupname", "a t1\na t2\n").find("line 2: the name 'a' is used twice"), std::string::npos);
  const std::string dup = message("duptoken", "a t1\nb t1\n");
  EXPECT_NE(dup.find("line 2: this token is used twice"), std::string::npos);
  EXPECT_EQ(dup.find("t1"), std::string::npos) << "a token must not appear in a message";
  EXPECT_NE(message("missing/none", "").find("cannot read it"), std::string::npos);
}

TEST(Authenticator, NamesTheClientTokenAndRefusesOthers) {
  Authenticator a({{"alice", "ta"}, {"bob", "tb"}}, "tw");
  EXPECT_EQ(a.clientTokenName("ta"), "alice");
  EXPECT_EQ(a.clientTokenName("tb"), "bob");
  EXPECT_FALSE(a.clientTokenName("tw"));
  EXPECT_FALSE(a.clientTokenName(""));
  EXPECT_TRUE(a.enabled(CallerRole::Client));
  Authenticator off({}, "");
  EXPECT_FALSE(off.enabled(CallerRole::Client));
  EXPECT_FALSE(off.enabled(CallerRole::Worker));
}

}  // namespace
}  // namespace invr::server
