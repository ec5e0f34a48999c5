"""A recording in a Jupyter notebook: the Rerun viewer inline (``rerun-notebook``, the same
version as the SDK), showing a ``.rrd`` file with its own default layout."""

from __future__ import annotations

from pathlib import Path

from workbench.errors import WorkbenchError


class StoredBlueprint:
    """A recording's own default blueprint (its chunks, read from the file) as what the SDK's
    ``blueprint=`` parameters take: they ask for ``to_blueprint()`` and ``_log_to_stream(stream)``."""

    def __init__(self, path: Path) -> None:
        from workbench.recording.blueprints import blueprint_chunks

        self.chunks = blueprint_chunks(Path(path))[1]

    def to_blueprint(self) -> StoredBlueprint:
        return self

    def _log_to_stream(self, stream) -> None:
        stream.send_chunks(self.chunks)


def show(path: str | Path, width: int | None = None, height: int = 720) -> None:
    """Show the recording at ``path`` in the notebook, in the layout it opens with."""
    import rerun as rr
    from rerun.chunk import RrdReader
    from rerun.notebook import Viewer

    path = Path(path)
    if not path.is_file():
        raise WorkbenchError(f"no such recording: {path}")
    reader = RrdReader(str(path))
    (entry, *_) = reader.recordings() or [None]
    if entry is None:
        raise WorkbenchError(f"{path} holds no recording")
    rec = rr.RecordingStream(entry.application_id, recording_id=entry.recording_id)
    viewer = Viewer(width=width, height=height, recording=rec, blueprint=StoredBlueprint(path))
    rec.send_chunks(reader.store(store=entry))
    rec.flush()
    viewer.display()
