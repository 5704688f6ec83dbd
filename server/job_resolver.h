// ResolveJob: a client's job (zoo name, job JSON, Mitsuba scene) with its overrides resolved into
// one self-contained JobSpec by core's resolver (core/job/job_source.h), the same code the CLI runs
// locally, over the files the client uploaded. The uploads are linked into a private temporary
// folder at the paths the job names them by; nothing outside it is read.
#pragma once

#include <grpcpp/grpcpp.h>

#include "invr/v1/service.pb.h"
#include "server/asset_store.h"

namespace invr::server {

// OK with resp.spec set, or with resp.missing_files naming what to upload next;
// INVALID_ARGUMENT naming the field or file at fault otherwise.
grpc::Status resolveJobRequest(const invr::v1::ResolveJobRequest& req, const AssetStore& assets, invr::v1::ResolveJobResponse& resp);

}  // namespace invr::server
