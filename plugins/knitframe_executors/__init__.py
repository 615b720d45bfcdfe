"""Built-in executors for many independent jobs: ``local`` (this process or a process pool) and
``dask`` (a dask.distributed cluster), plugins of kind ``"executor"``.

The ``[executor]`` table that chooses one, and the bookkeeping they share, are in
:mod:`knitframe.executors`; the result cache is :mod:`knitframe.cache`.
"""
