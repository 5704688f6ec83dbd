// The unit-test binaries' precompiled header (tests/CMakeLists.txt): GoogleTest, the schema's
// generated headers and the standard library, which every test file parses and which took about
// half of each one's compile time.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "invr/v1/job.pb.h"
#include "invr/v1/scene.pb.h"
#include "invr/v1/stats.pb.h"
