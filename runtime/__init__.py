"""crowdweave runtime: the engine a shipped game embeds (never imports ``authoring``)."""
__version__ = "0.1.0"
