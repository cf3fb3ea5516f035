"""The vehicle: assembles `struts` and `terrain` into a multi-axle hull DAE and runs scenarios."""
