"""Reads a slidetrack session with the official MCAP reader and checks it.

Usage: check_session.py FILE TOPIC [TOPIC ...]

Every listed topic must be present with at least one message; every message's
JSON payload must carry exactly the properties its channel's JSON Schema
declares (recursively for nested objects) and every required one. Prints a
JSON summary: message counts per topic and the metadata record names.
"""
import json
import sys

from mcap.reader import make_reader


def check(value, schema, where):
    kind = schema.get("type")
    kinds = kind if isinstance(kind, list) else [kind]
    if value is None:
        assert "null" in kinds, f"{where}: null where {kinds} expected"
        return
    if "object" in kinds and isinstance(value, dict):
        props = schema.get("properties", {})
        extra = set(value) - set(props)
        assert not extra, f"{where}: fields {sorted(extra)} not in the schema"
        missing = set(schema.get("required", [])) - set(value)
        assert not missing, f"{where}: required fields {sorted(missing)} missing"
        for k, v in value.items():
            check(v, props[k], f"{where}.{k}")
    elif "array" in kinds and isinstance(value, list):
        items = schema.get("items")
        if isinstance(items, dict):
            for i, v in enumerate(value):
                check(v, items, f"{where}[{i}]")
    elif "number" in kinds or "integer" in kinds:
        assert isinstance(value, (int, float)) and not isinstance(value, bool), f"{where}: {value!r} not a number"
    elif "boolean" in kinds:
        assert isinstance(value, bool), f"{where}: {value!r} not a boolean"
    elif "string" in kinds:
        assert isinstance(value, str), f"{where}: {value!r} not a string"


def main():
    path, wanted = sys.argv[1], sys.argv[2:]
    counts = {}
    with open(path, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        for schema, channel, message in reader.iter_messages():
            assert channel.message_encoding == "json", channel.topic
            assert schema.encoding == "jsonschema", schema.name
            payload = json.loads(message.data)
            check(payload, json.loads(schema.data), channel.topic)
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
        metadata = [m.name for m in reader.iter_metadata()]
    missing = [t for t in wanted if counts.get(t, 0) == 0]
    assert not missing, f"topics without messages: {missing}"
    assert summary is not None and summary.statistics is not None, "no summary"
    print(json.dumps({"counts": counts, "metadata": metadata}))


if __name__ == "__main__":
    main()
