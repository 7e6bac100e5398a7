"""The service's routes, one module per resource (thin: parse, call the registry or a worker, map the result)."""
