"""One module per format family; each registers a :class:`xtopo.io.registry.Format`."""
