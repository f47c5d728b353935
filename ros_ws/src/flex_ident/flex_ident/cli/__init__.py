"""Command-line tools (``flex-ident``)."""
