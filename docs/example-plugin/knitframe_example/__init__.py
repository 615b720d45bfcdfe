"""An example third-party knitframe plugin package: the ``tuck`` pattern and the ``force-extension`` reader."""
