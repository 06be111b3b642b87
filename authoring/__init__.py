"""crowdweave authoring: offline tools that turn motion data into runtime assets."""
