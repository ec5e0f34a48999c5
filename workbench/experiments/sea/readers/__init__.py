"""The readers of real files for ``scenario ais``: the AIS reports (``ais``), the UAV's GPS log
(``uav``) and the CSV reading with its repairs that both share (``csvfile``)."""
