"""Built-in executors for many independent jobs."""
