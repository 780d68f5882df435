"""Writes an EEMP run's Rerun recording with Python's rerun-sdk.

`eemp` runs this (embedded in the binary, `python -u -X utf8 -c ...`) when it records without
Rerun's Rust SDK, and feeds it on stdin: a header line (target, layout), then one JSON array of log
operations per line (crates/eemp-viz/src/ops.rs says what each means). It answers on stdout:
`ready` once the target is open, or `error: ...`, and `done <failed log calls> <1 if written
out, else 0>` at the end.

The geometry is computed on the Rust side; this only turns each operation into a log call.
Everything on the timeline (poses, series, points, polylines, arrows) is batched into columns
per entity (`send_columns`) and sent every FLUSH_S of wall time or FLUSH_ROWS rows (checked as
messages arrive, which at a live run's pace is every frame).
"""

import sys

# Run with -c, the current folder comes first on the path: a stray rerun.py (or json.py) in the
# folder a walk runs in must not shadow the real modules.
if sys.path and sys.path[0] == "":
    del sys.path[0]

import json  # noqa: E402
import os  # noqa: E402
import signal  # noqa: E402
import time  # noqa: E402

np = None  # numpy, imported with rerun (one of its dependencies)

FLUSH_S = 0.2
FLUSH_ROWS = 20000
# A viewer may be gone: a stream gets this long to be written out (a file is waited for).
STREAM_FLUSH_TIMEOUT_S = 5.0


def reply(line):
    try:
        sys.stdout.write(line + "\n")
        sys.stdout.flush()
    except BrokenPipeError:
        pass  # eemp stopped waiting for us (its own time limit); nothing to tell it


def blueprint(rrb, layout):
    def series(v):
        return rrb.TimeSeriesView(name=v["name"], origin=v["origin"])

    rows = [series(r[0]) if len(r) == 1 else rrb.Tabs(*[series(v) for v in r]) for r in layout["rows"]]
    scene = rrb.Spatial3DView(name=layout["scene_name"], origin=layout["scene_origin"])
    plots = rrb.Vertical(*rows, row_shares=layout["row_shares"])
    return rrb.Blueprint(
        rrb.Horizontal(scene, plots, column_shares=layout["column_shares"]),
        rrb.TimePanel(timeline=layout["timeline"]),
    )


class Columns:
    """Everything logged on the timeline, buffered per entity and sent as columns: one
    send_columns per entity and flush instead of one log call (and one archetype built in
    Python) per entity and frame, which made the bridge several times slower."""

    def __init__(self, rr, rec, timeline):
        self.rr, self.rec, self.timeline = rr, rec, timeline
        self.scalars = {}
        self.transforms = {}
        # path -> (archetype, times, {component: (values, lengths per row)})
        self.geometry = {}
        self.rows = 0
        self.last = time.monotonic()

    def shapes(self, t, path, archetype, components):
        """One row of points, polylines or arrows: `components` maps each component to its
        values in this row (a row may hold none: the entity is then empty from t on)."""
        _, times, columns = self.geometry.setdefault(path, (archetype, [], {}))
        times.append(t)
        for name, values in components.items():
            chunks, lengths = columns.setdefault(name, ([], []))
            chunks.append(values)
            lengths.append(len(values))
        self.rows += 1

    def scalar(self, t, path, value):
        times, values = self.scalars.setdefault(path, ([], []))
        times.append(t)
        values.append(value)
        self.rows += 1

    def transform(self, t, path, translation, quaternion_xyzw):
        times, ts, qs = self.transforms.setdefault(path, ([], [], []))
        times.append(t)
        ts.append(translation)
        qs.append(quaternion_xyzw)
        self.rows += 1

    def due(self):
        return self.rows >= FLUSH_ROWS or time.monotonic() - self.last >= FLUSH_S

    def flush(self, count):
        """Sends every buffered column; a path that fails (building or sending its columns) is
        counted and the rest still sent. The buffers are emptied first, so that a bad path is
        never sent again."""
        rr = self.rr
        scalars, transforms, geometry = self.scalars, self.transforms, self.geometry
        self.scalars, self.transforms, self.geometry = {}, {}, {}
        self.rows = 0
        self.last = time.monotonic()

        def scalar_columns(values):
            return rr.Scalars.columns(scalars=values)

        def transform_columns(ts, qs):
            return rr.Transform3D.columns(translation=ts, quaternion=qs)

        def shape_columns(archetype, columns):
            parts = []
            for name, (chunks, lengths) in columns.items():
                if isinstance(chunks[0], np.ndarray):
                    values = np.concatenate(chunks)
                else:
                    values = [v for chunk in chunks for v in chunk]
                parts.extend(archetype.columns(**{name: values}).partition(lengths))
            return parts

        sends = [(p, t, scalar_columns, (v,)) for p, (t, v) in scalars.items()]
        sends += [(p, t, transform_columns, (ts, qs)) for p, (t, ts, qs) in transforms.items()]
        sends += [(p, t, shape_columns, (a, c)) for p, (a, t, c) in geometry.items()]
        for path, times, build, args in sends:
            try:
                self.rec.send_columns(
                    path, indexes=[rr.TimeColumn(self.timeline, duration=times)], columns=build(*args)
                )
            except Exception as e:  # noqa: BLE001 -- counted, the rest is still sent
                count(f"columns of {path}", e)


def shape(rr, s, colour):
    kind = s["kind"]
    solid = rr.components.FillMode.Solid
    if kind == "sphere":
        return rr.Ellipsoids3D(radii=[s["radius"]], colors=[colour], fill_mode=solid)
    if kind == "ellipsoid":
        return rr.Ellipsoids3D(half_sizes=[s["half_sizes"]], colors=[colour], fill_mode=solid)
    if kind == "capsule":
        return rr.Capsules3D(
            lengths=[s["length"]],
            radii=[s["radius"]],
            translations=[[0.0, 0.0, s["z_start"]]],
            colors=[colour],
            fill_mode=solid,
        )
    if kind == "cylinder":
        return rr.Cylinders3D(lengths=[s["length"]], radii=[s["radius"]], colors=[colour], fill_mode=solid)
    if kind == "box":
        return rr.Boxes3D(half_sizes=[s["half_sizes"]], colors=[colour], fill_mode=solid)
    if kind == "mesh":
        return rr.Mesh3D(vertex_positions=s["vertices"], triangle_indices=s["triangles"], albedo_factor=colour)
    raise ValueError(f"unknown shape {kind!r}")


def v3(points):
    # An (n, 3) array converts far faster than nested lists (rerun-sdk's profile of a walk).
    return np.asarray(points, dtype=np.float32).reshape(-1, 3)


def rgba(colours):
    return np.asarray(colours, dtype=np.uint8).reshape(-1, 4)


def log_op(rr, rec, columns, now, op):
    kind = op["op"]
    if kind == "time":
        rec.set_time(columns.timeline, duration=op["t"])
        return op["t"]
    if kind == "scalar":
        columns.scalar(now, op["path"], op["value"])
    elif kind == "transform":
        # eemp (as MuJoCo) writes w, x, y, z; Rerun takes x, y, z, w.
        w, x, y, z = op["quaternion_wxyz"]
        if op["static"]:
            rec.log(
                op["path"],
                rr.Transform3D(translation=op["translation"], quaternion=[x, y, z, w]),
                static=True,
            )
        else:
            columns.transform(now, op["path"], op["translation"], [x, y, z, w])
    elif kind == "points":
        columns.shapes(
            now,
            op["path"],
            rr.Points3D,
            {"positions": v3(op["points"]), "colors": rgba(op["colours"]), "radii": [op["radius"]]},
        )
    elif kind == "strips":
        columns.shapes(
            now,
            op["path"],
            rr.LineStrips3D,
            {
                "strips": [v3(s) for s in op["strips"]],
                "colors": rgba(op["colours"]),
                "radii": [op["radius"]],
                "labels": op["labels"],
            },
        )
    elif kind == "arrows":
        columns.shapes(
            now,
            op["path"],
            rr.Arrows3D,
            {
                "vectors": v3(op["vectors"]),
                "origins": v3(op["origins"]),
                "colors": rgba([op["colour"]]),
                "radii": [op["radius"]],
            },
        )
    elif kind == "shape":
        rec.log(op["path"], shape(rr, op["shape"], op["colour"]), static=True)
    elif kind == "series_style":
        rec.log(op["path"], rr.SeriesLines(names=[op["name"]], colors=[op["colour"]]), static=True)
    else:
        raise ValueError(f"unknown operation {kind!r}")
    return now


def open_recording(header):
    global np
    try:
        import numpy as np
        import rerun as rr
        import rerun.blueprint as rrb
    except ImportError as e:
        reply(
            f"error: {sys.executable} cannot import rerun ({e}): "
            f"pip install rerun-sdk=={header['version']}"
        )
        return None
    have, want = rr.__version__.split(".")[:2], header["version"].split(".")[:2]
    if have != want:
        reply(
            f"error: {sys.executable} has rerun-sdk {rr.__version__}, the recorder writes "
            f"{header['version']}: pip install rerun-sdk=={header['version']}"
        )
        return None
    # Bad data raises instead of warning, so that eemp counts it.
    rr.set_strict_mode(True)
    rec = rr.RecordingStream(header["application_id"])
    bp = blueprint(rrb, header["layout"])
    target = header["target"]
    try:
        if "file" in target:
            rec.save(target["file"])
        elif "connect" in target:
            rec.connect_grpc(target["connect"])
        else:
            rec.serve_grpc(grpc_port=target["serve"], server_memory_limit="25%")
        # Active as well as default, as the Rust SDK's with_blueprint: a viewer that already
        # has an eemp layout shows this one.
        rec.send_blueprint(bp, make_active=True, make_default=True)
        rec.send_recording_name(header["recording_name"])
        rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    except Exception as e:  # noqa: BLE001 -- any failure to open is reported to eemp
        if "file" in target and os.path.exists(target["file"]):
            os.remove(target["file"])  # a recording that never started: leave nothing
        reply(f"error: cannot open the Rerun recording: {e}")
        return None
    return rr, rec


def main():
    # eemp ends this by closing stdin, also on Ctrl-C (which reaches this process too): write
    # out what was received instead of dying half-way.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    header = json.loads(sys.stdin.readline())
    opened = open_recording(header)
    if opened is None:
        return 2
    rr, rec = opened
    columns = Columns(rr, rec, header["layout"]["timeline"])
    reply("ready")
    failed = 0

    def count(what, e):
        nonlocal failed
        failed += 1
        if failed <= 3:
            print(f"eemp rerun bridge: {what}: {e}", file=sys.stderr)

    to_file = "file" in header["target"]
    flushed = True
    now = 0.0
    try:
        for line in sys.stdin:
            try:
                ops = json.loads(line)
            except ValueError as e:  # a line cut short: eemp stopped mid-write
                count("a message", e)
                continue
            for op in ops:
                try:
                    now = log_op(rr, rec, columns, now, op)
                except Exception as e:  # noqa: BLE001 -- counted and reported, the run goes on
                    count(f"{op.get('op')} {op.get('path', '')}", e)
            if columns.due():
                columns.flush(count)
    finally:
        columns.flush(count)
        try:
            if to_file:
                rec.flush()
                rec.disconnect()
            else:
                rec.flush(timeout_sec=STREAM_FLUSH_TIMEOUT_S)
        except Exception as e:  # noqa: BLE001 -- a viewer gone: the recording ends short
            flushed = False
            count("writing out", e)
        reply(f"done {failed} {int(flushed)}")
    if not to_file:
        # Closing a stream to a viewer that never answers waits forever (rerun-sdk 0.36.3's
        # disconnect and exit hooks): what could be sent was, so leave without them.
        sys.stderr.flush()
        os._exit(0)
    return 0


if __name__ == "__main__":
    sys.exit(main())
