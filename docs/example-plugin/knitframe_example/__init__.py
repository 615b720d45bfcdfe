"""An example third-party knitframe plugin package."""
