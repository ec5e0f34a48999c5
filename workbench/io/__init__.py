"""Files: text tables read with the repairs real exports need (:mod:`.text`), CSV rows with
their checks and time order (:mod:`.csvfiles`), and the open log formats' manifests
(:mod:`.logs`)."""
