"""A recording's own default layout read back from the file: its blueprint's chunks, the tree of
containers and views it asks the viewer for (names, view classes, origins), and blueprints
(``.rbl``) that are the recording's own with each tab in front (what a browser or a notebook
shows it with)."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

from workbench.errors import WorkbenchError

CONTAINER_KINDS = {1: "tabs", 2: "horizontal", 3: "vertical", 4: "grid"}


@dataclass
class Node:
    """A view or container of a recording's default blueprint."""

    id: str                       # "view/<uuid>" or "container/<uuid>"
    kind: str                     # a view's class (TimeSeries, 3D, TextDocument, ...) or a container kind
    name: str = ""
    origin: str = ""
    children: list[Node] = field(default_factory=list)
    properties: dict = field(default_factory=dict)  # the view's other blueprint components, by name

    @property
    def is_view(self) -> bool:
        return self.id.startswith("view/")

    def walk(self) -> Iterator[Node]:
        yield self
        for c in self.children:
            yield from c.walk()

    def views(self) -> list[Node]:
        return [n for n in self.walk() if n.is_view]


def blueprint_chunks(path: Path) -> tuple[str, list]:
    from rerun.chunk import RrdReader

    reader = RrdReader(str(path))
    stores = reader.blueprints()
    if not stores:
        raise WorkbenchError(f"{path} holds no blueprint (no default layout)")
    return stores[0].application_id, list(reader.store(store=stores[0]).stream())


def layout(path: Path) -> Node:
    """The recording's default blueprint as a tree of containers and views (names, view
    classes, origins), read from the file itself."""
    _, chunks = blueprint_chunks(path)
    rows: dict[str, dict] = {}
    root = None
    for ch in chunks:
        batch = ch.to_record_batch()
        entity = str(ch.entity_path).lstrip("/")
        values = {n.split(":", 1)[1] if ":" in n else n: batch.column(n).to_pylist()[-1]
                  for n in batch.schema.names if ":" in n}
        if entity == "viewport" and values.get("root_container"):
            import uuid

            root = "container/" + str(uuid.UUID(bytes=bytes(values["root_container"][0])))
        parts = entity.split("/")
        if len(parts) == 2 and parts[0] in ("view", "container"):
            rows.setdefault(entity, {}).update(values)
        elif len(parts) == 3 and parts[0] == "view":
            rows.setdefault("/".join(parts[:2]), {}).setdefault("properties", {})[parts[2]] = values
    if root is None or root not in rows:
        raise WorkbenchError(f"{path}'s blueprint has no root container")

    def node(ident: str) -> Node:
        r = rows.get(ident, {})
        def first(key):
            return ((r.get(key) or [""])[0])
        if ident.startswith("view/"):
            return Node(ident, first("class_identifier"), first("display_name"), first("space_origin"),
                        properties=r.get("properties", {}))
        kind = CONTAINER_KINDS.get(first("container_kind"), "container")
        return Node(ident, kind, first("display_name"), children=[node(c) for c in r.get("contents") or []])

    return node(root)


def tab_blueprints(path: Path, folder: Path) -> list[tuple[str, Path]]:
    """Blueprints (``.rbl``) that are the recording's own, paused (the viewer plays a file as it
    opens it, so its picture never settles): first as it opens, then with each tab after the
    first in front: (the tab's name, or ``"default"``, and the file). Loaded beside the
    recording, the viewer shows that."""
    import rerun as rr
    from rerun import bindings
    from rerun.blueprint.archetypes import ContainerBlueprint, TimePanelBlueprint

    app_id, chunks = blueprint_chunks(path)
    tree = layout(path)
    fronts: list[tuple[str, Node | None, Node | None]] = [("default", None, None)]
    for tabs in (n for n in tree.walk() if n.kind == "tabs"):
        fronts += [(child.name or child.kind, tabs, child) for child in tabs.children[1:]]
    out, used = [], set()
    for k, (name, tabs, child) in enumerate(fronts):
        name = next(n for n in (name, *(f"{name} {i}" for i in range(2, len(fronts) + 2))) if n not in used)
        used.add(name)
        stream = rr.RecordingStream._from_native(bindings.new_blueprint(
            application_id=app_id, make_default=False, make_thread_default=False, default_enabled=True))
        stream.send_chunks(chunks)
        stream.set_time("blueprint", sequence=2**40)
        if tabs is not None:
            stream.log(tabs.id, ContainerBlueprint.from_fields(active_tab=child.id))
        stream.log("time_panel", TimePanelBlueprint.from_fields(play_state="paused"))
        target = folder / f"{path.stem}.view{k}.rbl"
        bindings.save_blueprint(str(target), stream.to_native())
        out.append((name, target))
    return out
