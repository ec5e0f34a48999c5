"""The sea experiment's estimators: the paper's (``geometric``, the AR-model filters of ``ar_filter``)
and the baselines (``ekf``, the GTSAM smoothers of ``smoother`` and ``fixed_lag``, Stone Soup's trackers)."""
