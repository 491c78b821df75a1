"""Tools that read a finished analysis result (``info``, ``export``, ``plot``, ``merge``),
through :mod:`clothtool.io.result`."""
