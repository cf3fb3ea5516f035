"""Road profiles: ISO 8608 random roads, discrete events, measured profiles (no vehicle knowledge)."""
