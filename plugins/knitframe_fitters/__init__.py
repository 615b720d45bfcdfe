"""Built-in fitters: reduced-model parameters from Responses."""
