"""What is computed from results (read-only numbers): per-axle summary, ride metrics, PSD.

    summary       per-axle numbers read back from results
    ride_metrics  ISO 2631 ride numbers per seat
    psd           power spectral densities of stored series
    measurements  measurement files (points per axle or wheel, logged series: CSV, MDF4)
    instruments   what an instrument reads of a prediction (pyrometer, photogrammetry, scale)
    internal_drift  how an integrated strut's damping and friction moved with temperature over a drive
"""
