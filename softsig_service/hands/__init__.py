"""Hand models: manifests (hand.toml), model loading (MJCF/URDF) and simulated closure."""
