"""LeRobot datasets from recorded episodes (``stage=dataset``)."""
