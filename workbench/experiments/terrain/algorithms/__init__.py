"""The terrain experiment's estimators: the recurrent search and its search space, the compiled
kernel, the posterior, radiometry, bundle adjustment."""
