"""Built-in data-file readers."""
