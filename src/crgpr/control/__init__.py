"""Control on the learned port-Hamiltonian model (docs/control.md).

``statics``: the model's static equilibrium under tip inputs (feedforward by energy shaping);
``design``: regulation and tracking policies (feedforward + tip feedback, input limits);
``policy``: the portable policy law and its JSON/table form; ``closed_loop``: a digital
(zero-order hold) loop of a policy with a plant (the simulator or a learned rod); ``metrics``: the
closed-loop figures of merit; ``posterior``: one design per posterior sample of the learned model
and the odds that its loop converges.
"""
