"""Reads every message of MCAP files with the official `mcap` Python package
and checks it, independently of echofield's Rust reader.

For each file:
- a linear pass (NonSeekingReader, chunk and data-section CRCs checked) in file
  order, and an indexed pass (SeekingReader, through the summary and chunk
  indexes, as Foxglove reads) in log-time order; both must see the same number
  of messages, which must match the summary statistics;
- `json` channels: every message parses as strict JSON (no NaN/Infinity) and
  validates against its channel's `jsonschema` schema (draft 2020-12, via the
  `jsonschema` package); fields marked `"contentEncoding": "base64"` must be
  valid base64; a message with `stamp_s` must have log_time = round(stamp_s * 1e9);
- `cdr` channels with `ros2msg` schemas: every message decodes with
  `mcap-ros2-support`;
- the `echofield.mission` metadata record, when present, holds
  `format_version` 1, a name and a JSON mounting.

Usage: python check_mcap.py FILE.mcap...   (exit status 1 on any error)
"""

import base64
import binascii
import json
import sys
from collections import Counter

import jsonschema
from mcap.reader import NonSeekingReader, SeekingReader
from mcap_ros2.decoder import DecoderFactory

MAX_ERRORS_SHOWN = 5


def reject_constant(name):
    raise ValueError(f"non-standard JSON number {name}")


def base64_paths(schema, path=()):
    """Paths (tuples of keys, '*' for array items) of base64 string fields."""
    if not isinstance(schema, dict):
        return
    if schema.get("contentEncoding") == "base64":
        yield path
    for key, sub in schema.get("properties", {}).items():
        yield from base64_paths(sub, path + (key,))
    if "items" in schema:
        yield from base64_paths(schema["items"], path + ("*",))


def values_at(value, path):
    if not path:
        yield value
        return
    head, rest = path[0], path[1:]
    if head == "*" and isinstance(value, list):
        for item in value:
            yield from values_at(item, rest)
    elif isinstance(value, dict) and head in value:
        yield from values_at(value[head], rest)


class FileCheck:
    def __init__(self, path):
        self.path = path
        self.errors = []
        self.validators = {}
        self.ros2 = DecoderFactory()
        self.ros2_decoders = {}

    def error(self, where, message):
        self.errors.append(f"{self.path}: {where}: {message}")

    def json_validator(self, schema):
        if schema.id not in self.validators:
            parsed = json.loads(schema.data)
            jsonschema.Draft202012Validator.check_schema(parsed)
            self.validators[schema.id] = (
                jsonschema.Draft202012Validator(parsed),
                list(base64_paths(parsed)),
            )
        return self.validators[schema.id]

    def check_json(self, where, schema, message):
        validator, b64_paths = self.json_validator(schema)
        value = json.loads(message.data, parse_constant=reject_constant)
        for err in validator.iter_errors(value):
            field = "/".join(str(p) for p in err.absolute_path) or "(message)"
            self.error(where, f"field `{field}`: {err.message}")
        for path in b64_paths:
            for text in values_at(value, path):
                try:
                    base64.b64decode(text, validate=True)
                except (binascii.Error, TypeError) as e:
                    self.error(where, f"field `{'/'.join(path)}`: bad base64: {e}")
        if isinstance(value, dict) and isinstance(value.get("stamp_s"), (int, float)):
            expected = round(value["stamp_s"] * 1e9)
            # Python's float product can differ from Rust's by one rounding.
            if abs(message.log_time - expected) > 1:
                self.error(where, f"log_time {message.log_time} != stamp_s in ns {expected}")

    def check_cdr(self, where, schema, channel, message):
        key = schema.id
        if key not in self.ros2_decoders:
            self.ros2_decoders[key] = self.ros2.decoder_for(channel.message_encoding, schema)
        decoder = self.ros2_decoders[key]
        if decoder is None:
            self.error(where, f"no ROS 2 decoder for schema `{schema.name}`")
            return
        decoded = decoder(message.data)
        if not hasattr(decoded, "header") and not hasattr(decoded, "transforms"):
            self.error(where, f"decoded `{schema.name}` has no header")

    def check_message(self, index, schema, channel, message):
        where = f"message {index} (topic `{channel.topic}`)"
        if schema is None:
            self.error(where, "channel has no schema")
            return
        try:
            if channel.message_encoding == "json" and schema.encoding == "jsonschema":
                self.check_json(where, schema, message)
            elif channel.message_encoding == "cdr" and schema.encoding == "ros2msg":
                self.check_cdr(where, schema, channel, message)
            else:
                self.error(
                    where,
                    f"cannot check encoding `{channel.message_encoding}` / `{schema.encoding}`",
                )
        except Exception as e:  # every decoding failure is a finding, not a crash
            self.error(where, f"{type(e).__name__}: {e}")

    def check_metadata(self, reader):
        for record in reader.iter_metadata():
            if record.name != "echofield.mission":
                continue
            meta = record.metadata
            if meta.get("format_version") != "1":
                self.error("metadata", f"format_version {meta.get('format_version')!r} != '1'")
            if "name" not in meta:
                self.error("metadata", "no `name`")
            try:
                mounting = json.loads(meta.get("mounting", ""))
                for key in ("vehicle_from_sonar", "vehicle_from_dvl"):
                    if len(mounting[key]) != 3:
                        self.error("metadata", f"mounting.{key} is not [x, y, theta]")
            except (ValueError, KeyError, TypeError) as e:
                self.error("metadata", f"bad mounting: {e}")

    def run(self):
        counts = Counter()
        kinds = {}
        with open(self.path, "rb") as f:
            reader = NonSeekingReader(f, validate_crcs=True)
            for index, (schema, channel, message) in enumerate(
                reader.iter_messages(log_time_order=False)
            ):
                counts[channel.topic] += 1
                kinds[channel.topic] = (
                    schema.name if schema else "-",
                    channel.message_encoding,
                )
                self.check_message(index, schema, channel, message)
        with open(self.path, "rb") as f:
            reader = SeekingReader(f, validate_crcs=True)
            indexed = sum(1 for _ in reader.iter_messages(log_time_order=True))
            summary = reader.get_summary()
            self.check_metadata(reader)
        linear = sum(counts.values())
        if indexed != linear:
            self.error("index", f"indexed pass saw {indexed} messages, linear pass {linear}")
        if summary is None or summary.statistics is None:
            self.error("summary", "no statistics record")
        elif summary.statistics.message_count != linear:
            self.error(
                "summary",
                f"statistics count {summary.statistics.message_count} != {linear} messages",
            )
        return counts, kinds


def main(paths):
    if not paths:
        print(__doc__)
        return 2
    failed = False
    for path in paths:
        check = FileCheck(path)
        try:
            counts, kinds = check.run()
        except Exception as e:
            check.error("file", f"{type(e).__name__}: {e}")
            counts, kinds = Counter(), {}
        status = "ok" if not check.errors else f"{len(check.errors)} ERRORS"
        print(f"{path}: {sum(counts.values())} messages, {status}")
        for topic in sorted(counts):
            name, encoding = kinds[topic]
            print(f"  {topic:<28} {name:<46} {encoding:<5} {counts[topic]:>8}")
        for line in check.errors[:MAX_ERRORS_SHOWN]:
            print(f"  ERROR {line}")
        if len(check.errors) > MAX_ERRORS_SHOWN:
            print(f"  ... and {len(check.errors) - MAX_ERRORS_SHOWN} more errors")
        failed |= bool(check.errors)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
