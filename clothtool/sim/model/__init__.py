"""What a run is made of: the config, and the Model built from it (warp.sim's split).

- :mod:`~clothtool.sim.model.config` and :mod:`~clothtool.sim.model.schema`: YAML → validated
  dataclasses, every key declared; :mod:`~clothtool.sim.model.methods`: the registry of methods
  and the features each supports;
- :mod:`~clothtool.sim.model.mesh`, :mod:`~clothtool.sim.model.pins`,
  :mod:`~clothtool.sim.model.seams`, :mod:`~clothtool.sim.model.attach`: the rest mesh, pin
  sets, seams and sewing, vertices carried by a collider;
- :mod:`~clothtool.sim.model.colliders`, :mod:`~clothtool.sim.model.motion`,
  :mod:`~clothtool.sim.model.contact_scene`: the colliders, rigid motions and the contact data;
- :mod:`~clothtool.sim.model.builder` assembles them into the
  :class:`~clothtool.sim.model.model.Model` (what does not change during a run); the
  :class:`~clothtool.sim.model.state.State` holds what does.

The model imports the energies and the linear algebra, never the solve.
"""
