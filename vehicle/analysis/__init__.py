"""Analysis of drive results: numbers computed from stored results (shock and crest-factor metrics of
vehicle.analysis.shocks; the summaries of vehicle.runs move here)."""
