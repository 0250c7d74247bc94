"""Launch, parameters and the `skynav` command."""
