"""Built-in sparse linear solvers (factories returning solve(A, b) closures)."""
