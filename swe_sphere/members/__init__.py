"""The member machinery below the driver (``simulation.Simulation``, of one member or N): the
one builder and state-and-diagnostics object of a run's members (``members.Members``), N disjoint
copies of one grid (``grid.MemberGrid``), how members start (``initial``: ``Perturbation``,
``MemberFile``, ``Variants``) and how a rank's members are stepped (``units``: in the same
launches on the copies, or each on a model of its own, and their stepper states in a restart
file).

May import: every layer below (``adjoint`` down to ``kernels``). Its modules are imported by name
(``members.members``, ``members.grid``, ``members.initial``, ``members.units``)."""
