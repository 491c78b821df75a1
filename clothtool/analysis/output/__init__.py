"""What ``analyze`` writes while it runs, beside the face fields: the per-pair ``/summary``,
frame positions, vertex averages (:mod:`clothtool.vertex_average`) and the slice attributes of
``--pairs``. The layout of a finished result and its reader are :mod:`clothtool.io.result`
(the XDMF beside it: :mod:`clothtool.io.xdmf`); the tools that read it are in
:mod:`clothtool.results`."""
