"""Built-in garment-design objectives."""
