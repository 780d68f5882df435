"""Reads a recording back with Rerun's own reader (rerun-sdk's RrdReader), for the tests.

usage: python read_rrd.py FILE.rrd ENTITY=COMPONENT...   (e.g. /world/robot/trunk=Transform3D:translation)
prints JSON: the recording's application id and name, every entity path, and for each requested
pair the rows on the sim_time timeline in time order, each row's values flattened.
"""

import json
import sys

import pyarrow as pa
import pyarrow.compute as pc
from rerun.experimental import RrdReader


def flatten(value):
    if isinstance(value, list):
        return [x for v in value for x in flatten(v)]
    return [value]


def main():
    path, wanted = sys.argv[1], [a.split("=", 1) for a in sys.argv[2:]]
    reader = RrdReader(path)
    [store] = reader.recordings()
    entities, rows, name = set(), {f"{e}={c}": [] for e, c in wanted}, None
    # stream(), not store(): also reads a file without a footer (a server's --save cut short).
    for chunk in reader.stream(store=store).to_chunks():
        entity = chunk.entity_path
        entities.add(entity)
        batch = chunk.to_record_batch()
        names = batch.schema.names
        if "RecordingInfo:name" in names:
            name = flatten(batch.column("RecordingInfo:name").to_pylist())[0]
        for e, c in wanted:
            if e != entity or c not in names or "sim_time" not in names:
                continue
            times = pc.cast(batch.column("sim_time"), pa.int64()).to_pylist()
            for t, v in zip(times, batch.column(c).to_pylist()):
                if v is not None:
                    rows[f"{e}={c}"].append((t, flatten(v)))
    out = {
        "application_id": store.application_id,
        "recording_name": name,
        "entities": sorted(entities),
        "rows": {k: [v for _, v in sorted(r, key=lambda tv: tv[0])] for k, r in rows.items()},
    }
    json.dump(out, sys.stdout)


if __name__ == "__main__":
    main()
