// A scene's optimisable parameters as the DescribeScene RPC and `invr params` report them.
#pragma once

#include "core/scene/scene.h"
#include "invr/v1/service.pb.h"

namespace invr {

invr::v1::SceneDescription describeScene(const Scene& scene);

}  // namespace invr
