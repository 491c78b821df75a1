"""What ``analyze`` writes while it runs, beside the face fields: the per-pair ``/summary``,
vertex averages, frame positions, the XDMF for ParaView and the slice attributes of
``--pairs``. The tools that read a finished result are in :mod:`clothtool.results`; the
reader itself is :mod:`clothtool.io.result`."""
