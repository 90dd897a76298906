"""One module per ``usdscene`` sub-command (discovered by ``usdscene.cli``)."""
