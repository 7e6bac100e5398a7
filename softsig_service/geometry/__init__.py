"""Pure numpy geometry: rigid transforms, minimum-volume ellipsoids, principal components."""
