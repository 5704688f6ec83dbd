"""Progress events and status messages as plain Python: dicts, lists, ints, floats, enum names."""

import base64
import math

from google.protobuf.descriptor import FieldDescriptor


def to_python(message):
    """A protobuf message as plain Python in invr's one JSON mapping (proto/wire/json_lines.h, the
    same as `invr ... --json`, progress.jsonl and the dashboard's API): field names as in the
    .proto files, enums by name, every number a number, non-finite values None, scalar fields
    always present, unset messages, oneof members and optionals left out, bytes as base64."""
    out = {}
    for field in message.DESCRIPTOR.fields:
        value = getattr(message, field.name)
        if field.message_type is not None and field.message_type.GetOptions().map_entry:
            vf = field.message_type.fields_by_name["value"]
            out[field.name] = {k: _value(vf, v) for k, v in value.items()}
        elif field.label == FieldDescriptor.LABEL_REPEATED:
            out[field.name] = [_value(field, v) for v in value]
        elif field.containing_oneof is not None or field.message_type is not None or field.has_presence:
            if message.HasField(field.name):
                out[field.name] = _value(field, value)
        else:
            out[field.name] = _value(field, value)
    return out


def _value(field, v):
    if field.type == FieldDescriptor.TYPE_MESSAGE:
        return to_python(v)
    if field.type == FieldDescriptor.TYPE_ENUM:
        ev = field.enum_type.values_by_number.get(v)
        return ev.name if ev is not None else v
    if isinstance(v, float) and not math.isfinite(v):
        return None
    if field.type == FieldDescriptor.TYPE_BYTES:
        return base64.b64encode(v).decode()
    return v


class Event:
    """One progress event with its fields as attributes.

    kind: "message", "step" or "final"; sequence; unix_ms; then
    - message: .message (lifecycle text)
    - step: .step, .steps, .loss (unbiased, may be negative), .image_loss (the one-render loss
      against the targets, smoothed over steps: biased, never negative; every job has it),
      .param_error / .shape_error (None when unknown), .seconds,
      .eta_seconds, .steps_per_second, .parameters (name -> list: scalar and small parameters),
      .stats (every counter, a dict)
    - final: .state ("SUCCEEDED", "FAILED", "CANCELLED"), .reason, .status (the JobStatus dict)
    """

    def __init__(self, data):
        self.data = data
        self.sequence = int(data.get("sequence", 0))
        self.unix_ms = int(data.get("unix_ms", 0))
        if "step" in data:
            self.kind = "step"
            s = data["step"]
            for k, v in s.items():
                setattr(self, k, _number(v))
            for k in ("param_error", "shape_error"):
                v = getattr(self, k, None)
                setattr(self, k, None if v is None or (isinstance(v, float) and (math.isnan(v) or v < 0)) else v)
            self.parameters = {p["name"]: p["values"] for p in s.get("parameters", [])}
        elif "final" in data:
            self.kind = "final"
            self.status = data["final"]
            self.state = self.status.get("state")
            self.reason = self.status.get("reason", "")
        else:
            self.kind = "message"
            self.message = data.get("message", "")

    def __repr__(self):
        if self.kind == "step":
            return f"Event(step {self.step}/{self.steps}, loss {self.loss:.6g}, image_loss {self.image_loss:.6g})"
        if self.kind == "final":
            return f"Event(final {self.state}{': ' + self.reason if self.reason else ''})"
        return f"Event(message {self.message!r})"


def _number(v):
    if v is None:
        return float("nan")
    return v
