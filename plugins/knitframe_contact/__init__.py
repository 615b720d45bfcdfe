"""Built-in yarn-yarn contact laws."""
