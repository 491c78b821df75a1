"""What a simulation writes for animation tools, beside its PLY frames: OBJ frames with the
pattern's uv (:mod:`~clothtool.io.caches.obj_writer`), an MDD point cache
(:mod:`~clothtool.io.caches.mdd`) and a USD stage (:mod:`~clothtool.io.caches.usd`)."""
