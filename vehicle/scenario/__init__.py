"""Scenarios: what to drive and what to keep, validated before any work (schema, work limits)."""
