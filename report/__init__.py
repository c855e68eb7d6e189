"""Pictures of runs: maps, time series and the train animation (:mod:`.plots`)."""
