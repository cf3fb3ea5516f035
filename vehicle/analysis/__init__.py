"""Analysis of drive results: summaries and derived quantities read from a results file (above vehicle.runs)."""
