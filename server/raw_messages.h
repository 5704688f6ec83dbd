// The client API reads its requests itself. gRPC's callback API answers a request whose bytes do
// not parse as its message with UNIMPLEMENTED, which tells a client the method does not exist; the
// service takes raw bytes instead, parses them here and answers INVALID_ARGUMENT naming the message.
#pragma once

#include <grpcpp/grpcpp.h>
#include <grpcpp/impl/codegen/proto_utils.h>

#include <string>

namespace invr::server {

// Parses `bytes` into `msg`; INVALID_ARGUMENT when they are not a valid message of its type.
template <class Msg>
grpc::Status parseRequest(const grpc::ByteBuffer& bytes, Msg& msg) {
  grpc::ByteBuffer copy(bytes);  // deserialisation consumes its buffer
  grpc::Status st = grpc::SerializationTraits<Msg>::Deserialize(&copy, &msg);
  if (st.ok()) return st;
  return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                      "the request is not a valid " + Msg::descriptor()->full_name() + " (malformed or truncated bytes)");
}

template <class Msg>
grpc::ByteBuffer toBytes(const Msg& msg) {
  grpc::ByteBuffer out;
  bool own = false;
  (void)grpc::SerializationTraits<Msg>::Serialize(msg, &out, &own);
  return out;
}

// Raw methods' answers: the response message, serialised into the call's buffer when the status
// is OK.
template <class Msg>
grpc::ServerUnaryReactor* finishWith(grpc::CallbackServerContext* ctx, grpc::Status st, const Msg& resp, grpc::ByteBuffer* out) {
  if (st.ok()) *out = toBytes(resp);
  auto* reactor = ctx->DefaultReactor();
  reactor->Finish(std::move(st));
  return reactor;
}

}  // namespace invr::server
