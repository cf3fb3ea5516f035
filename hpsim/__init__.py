"""hpsim base layer: plumbing shared by `struts`, `terrain` and `vehicle`.

No physics lives here: only units, user-facing errors, safe YAML loading and
small command-line helpers. Dependency direction:

    hpsim  <-  struts, terrain  <-  vehicle (assembles the DAE, runs scenarios, CLI)
"""

__version__ = "0.1.0"
