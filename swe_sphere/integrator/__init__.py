"""The integrator layer: the package's one step loop (``core``: ``Integrator``, its ``Unit`` s,
the guard, the Δt policies ``FixedDt`` and ``ControlledDt``, the observer hooks) and the step
control it steps under a controlled Δt (``control``: ``StepControl``).
Every driver steps through it: a run of one member or many (``simulation.Simulation``) and the
gradient's sweeps (``adjoint.gradient``).

May import: every layer below (``config`` down to ``kernels``). Its modules are imported by
name (``integrator.core``, ``integrator.control``)."""
