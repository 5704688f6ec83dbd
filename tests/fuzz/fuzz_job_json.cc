// fuzz_job_json: parseJobJson (job files, `invr submit`, the server's SubmitJob), which runs
// validateJobSpec. A job it accepts must print with jobToJson and parse again, and printing must
// settle (the store and the client round-trip jobs through JSON); its asset references must walk.
#include <google/protobuf/stubs/logging.h>

#include <cstddef>
#include <cstdint>
#include <string>

#include "core/io/job_io.h"
#include "tests/fuzz/fuzz_common.h"

// protobuf logs every string field with invalid UTF-8 it parses (an expected outcome here) to
// stderr: quiet, so that the log shows the findings.
extern "C" int LLVMFuzzerInitialize(int*, char***) {
  google::protobuf::SetLogHandler(nullptr);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string json(reinterpret_cast<const char*>(data), size);
  invr::v1::JobSpec job;
  try {
    job = invr::parseJobJson(json, "fuzz.json");
  } catch (const invr::InputError& e) {
    invr::fuzz::rejected(e);
    return 0;
  }
  const std::string again = invr::jobToJson(job);
  try {
    invr::v1::JobSpec back = invr::parseJobJson(again, "roundtrip.json");
    // Printing reaches a fixed point after one more round trip. (Not at once: protobuf prints a
    // -0.0 it holds as "-0", which it parses back as 0 and then omits as a default value.)
    const std::string twice = invr::jobToJson(back);
    FUZZ_CHECK(invr::jobToJson(invr::parseJobJson(twice, "roundtrip2.json")) == twice, "the job keeps changing through JSON");
  } catch (const invr::InputError& e) {
    FUZZ_CHECK(false, std::string("an accepted job, printed by jobToJson, is rejected: ") + e.what());
  }
  size_t refs = 0;
  invr::forEachAssetRef(job, [&](invr::v1::AssetRef& ref, const std::string& path) {
    FUZZ_CHECK(!path.empty(), "an asset reference without a field path");
    refs += ref.ByteSizeLong() > 0;
  });
  invr::fuzz::accepted("job '" + job.name() + "', " + std::to_string(refs) + " asset reference(s)");
  return 0;
}
