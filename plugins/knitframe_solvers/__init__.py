"""Built-in unit-cell solvers."""
