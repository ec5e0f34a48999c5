"""Settings: scenarios and their defaults, command-line options, the config base and its JSON
(:mod:`.settings`), config files in TOML or JSON (:mod:`.files`), and the checks every
experiment's values share (:mod:`.checks`)."""
