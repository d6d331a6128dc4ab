"""Reading an adm-sim ``.rrd`` back (``rerun.chunk.RrdReader``): entities, blueprint, common checks."""

from __future__ import annotations

import re
from pathlib import Path

import pyarrow as pa

from adm_sim import protocol as P
from adm_sim.recording import rerun_blueprint as bp

def read_rrd(path: Path) -> dict:
    """Entities of the recording: path -> {"rows", "static", timeline -> int64 ns/seq, "values"}."""
    from rerun.chunk import RrdReader

    out: dict[str, dict] = {}
    for chunk in RrdReader(path).stream():
        e = out.setdefault(chunk.entity_path, {"rows": 0, "static": False, "times": {}, "values": [], "text": []})
        rb = chunk.to_record_batch()
        e["rows"] += chunk.num_rows
        e["static"] |= chunk.is_static
        for tl in chunk.timeline_names:
            e["times"].setdefault(tl, []).extend(rb.column(tl).cast(pa.int64()).to_pylist())
        for name in rb.schema.names:
            if name.endswith("Scalars:scalars"):
                e["values"].extend(v[0] for v in rb.column(name).to_pylist() if v)
            if name.endswith("TextDocument:text"):
                e["text"].extend(v[0] for v in rb.column(name).to_pylist() if v)
    return out


def read_blueprint(path: Path) -> dict:
    """The last blueprint store of the file: views (name, class, origin, query), tabs, timeline."""
    from rerun.chunk import RrdReader

    reader = RrdReader(path)
    stores = reader.blueprints()
    assert stores, f"{path} carries no blueprint"
    views: dict[str, dict] = {}
    tabs, timeline = [], None
    for chunk in reader.stream(store=stores[-1]):
        rb = chunk.to_record_batch()
        keys = ("display_name", "class_identifier", "space_origin", "query", "timeline")
        cols = {n.split(":")[-1]: rb.column(n).to_pylist() for n in rb.schema.names if n.split(":")[-1] in keys}
        p = chunk.entity_path
        if p.startswith("/view/"):
            vid = p.split("/")[2]
            v = views.setdefault(vid, {})
            for key in ("display_name", "class_identifier", "space_origin", "query"):
                if key in cols and cols[key][-1]:
                    v[key] = cols[key][-1] if key == "query" else cols[key][-1][0]
        if p.startswith("/container/") and "display_name" in cols:
            tabs.append(cols["display_name"][-1][0])
        if p == "/time_panel" and "timeline" in cols:
            timeline = cols["timeline"][-1][0]
    return {"views": list(views.values()), "tabs": tabs, "timeline": timeline}


def view_entities(view: dict, entities: dict) -> list[str]:
    """Entities of the recording that a view shows (``$origin/**`` queries)."""
    origin = "/" + view["space_origin"].strip("/")
    assert view.get("query", ["$origin/**"]) == ["$origin/**"]
    return [p for p, e in entities.items() if (p == origin or p.startswith(origin + "/")) and not p.startswith("/__")]


def check_recording(path: Path) -> tuple[dict, dict]:
    """Checks every adm-sim recording must pass; returns (entities, blueprint)."""
    ents = read_rrd(path)
    blue = read_blueprint(path)
    assert set(bp.TABS) <= set(blue["tabs"])
    assert blue["timeline"] == bp.RUN_TIME
    assert len(blue["views"]) == 9
    for view in blue["views"]:  # views and logged entities: all in the protocol's one table
        assert P.is_entity(view["space_origin"]), view
    for p in ents:
        assert p.startswith("/__") or P.is_entity(p), f"entity {p} is not below a root of adm_sim.protocol.ENTITIES"
    for view in blue["views"]:
        name = view["display_name"]
        assert re.search(r"\[(m/s²|%|m|s|km/h)\]", name) or view["class_identifier"] == "TextDocument", name
        if view["class_identifier"] == "TimeSeries":  # the timeline it needs, by name
            assert any(tl in name for tl in bp.TIMELINES), name
    runs = [p for p in ents if re.fullmatch(r"/runs/acceleration/run_\d\d", p)]
    assert runs
    for p in runs:  # every run starts at run time 0 (first sample at train entry, k = 0)
        assert min(ents[p]["times"][bp.RUN_TIME]) == 0, p
        assert len(ents[p]["times"][bp.SIM_TIME]) == len(ents[p]["times"][bp.RUN_TIME])
    for p, e in ents.items():  # no number printed like 1.8500000000000003
        for text in e["text"]:
            assert not re.search(r"\d\.\d{7,}", text), (p, text)
    return ents, blue


