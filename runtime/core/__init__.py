"""The compiled core, shared by both solver plans: the plan as plain arrays (model), the state (data), buffers
(scratch), and the kernels that read them. See docs/solver.md ("The compiled core")."""
