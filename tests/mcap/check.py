"""Opens video2track MCAP recordings with the MCAP project's own Python reader (PyPI `mcap`) and
checks what Foxglove and other tools will see: every channel present with its schema and encoding,
every message valid JSON, log times in order per channel, the run metadata present.

    python check.py RUN.mcap [RUN.mcap ...]
"""

import json
import sys

from mcap.reader import make_reader

EXPECTED = {
    "/truth": "v2t.Truth",
    "/scene": "foxglove.SceneUpdate",
    "/commands": "v2t.Commands",
    "/pet": "v2t.PredictedPet",
    "/plans": "v2t.Plan",
}


def check(path):
    counts = {topic: 0 for topic in EXPECTED if topic != "/plans"}
    last = {}
    with open(path, "rb") as f:
        reader = make_reader(f)
        for schema, channel, message in reader.iter_messages(log_time_order=False):
            topic = channel.topic
            if topic not in EXPECTED:
                raise SystemExit(f"{path}: unexpected channel {topic}")
            if schema is None or schema.name != EXPECTED[topic] or schema.encoding != "jsonschema":
                raise SystemExit(f"{path}: {topic}: schema {schema and (schema.name, schema.encoding)}")
            json.loads(schema.data)
            if channel.message_encoding != "json":
                raise SystemExit(f"{path}: {topic}: encoding {channel.message_encoding}")
            json.loads(message.data)
            if message.log_time < last.get(topic, 0):
                raise SystemExit(f"{path}: {topic}: log time goes back at message {message.sequence}")
            last[topic] = message.log_time
            counts[topic] = counts.get(topic, 0) + 1
        meta = {m.name: m.metadata for m in reader.iter_metadata()}
    run = meta.get("video2track.run")
    if run is None or not {"setup", "agents", "result"} <= set(run):
        raise SystemExit(f"{path}: no video2track.run metadata with setup, agents and result")
    result = json.loads(run["result"])
    empty = [t for t, n in counts.items() if n == 0]
    if empty:
        raise SystemExit(f"{path}: no messages on {empty}")
    print(f"{path}: {counts}, PET_min {result.get('pet_min_s')}")


if __name__ == "__main__":
    if len(sys.argv) < 2:
        raise SystemExit(__doc__)
    for p in sys.argv[1:]:
        check(p)
