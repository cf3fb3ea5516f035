"""Analysis of results: numbers drawn from drives and measurements (per-axle summaries, ride metrics, measurement
files and the instruments that read them)."""
