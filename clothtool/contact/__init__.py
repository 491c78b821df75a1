"""Contact between cloth, itself and triangle-mesh colliders, kept free of intersections.

The method is Incremental Potential Contact (Li et al. 2020, "Incremental Potential
Contact"; codimensional IPC with a thickness, Li et al. 2021): a log-barrier on the
vertex–triangle and edge–edge distances joins the incremental potential, and every
step of the Newton line search is cut to a collision-free fraction by additive CCD,
so that no iterate ever passes through another surface. The modules are pure numba
kernels over one vertex array that holds the cloth and the colliders (a boolean
``obstacle`` per vertex marks collider vertices):

- ``broadphase``: boxes of positions or of motions, a uniform grid, candidate pairs;
- ``distance``: closest points of vertex–triangle and edge–edge pairs;
- ``barrier``: the barrier energy, its gradient and a Gauss–Newton Hessian;
- ``ccd``: the collision-free step fraction (additive CCD);
- ``friction``: IPC's smoothed Coulomb friction, lagged;
- ``pieces``: Newton's stick–slip residual test on the rigid motions of each piece of cloth;
- ``intersect``: an exact triangle-mesh intersection test, the independent check;
- ``projection``: planes and spheres by projection, for the methods without barrier contact.
"""
