"""Making analysis results usable elsewhere: ParaView (XDMF), summaries, coloured PLY,
plots, and joining results computed in slices on several machines."""
