"""Built-in weft-knit patterns: jersey, garter, 1x1 rib and seed, all built from :mod:`.loops`."""
