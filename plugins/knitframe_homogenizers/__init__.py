"""Built-in reduced-order fabric models (homogenizers)."""
