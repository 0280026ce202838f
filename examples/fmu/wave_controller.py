"""An open-loop controller as an FMU: the travelling wave f(x, t) = f0 sin(k x - omega t + phase).

Built into a co-simulation FMU (FMI 2.0) with pythonfmu (pinned in requirements.txt):

    .venv/bin/python -m pythonfmu build -f examples/fmu/wave_controller.py -d OUT_DIR

which writes OUT_DIR/WaveController.fmu. Its outputs `wave_f0` (N), `wave_k` (rad/m),
`wave_omega` (rad/s) and `wave_phase` (rad) are wired to the plant FMU's inputs of the same names
by examples/fmu/crawler.ssd (scripts/build-ssp.sh packs both FMUs with it into an SSP file). The
outputs are the parameters `f0`, `k`, `omega` and `phase` (starts: the plant FMU's, the paper
scenario's wave; the SSP file sets its own), read whenever the master asks, so the plant is driven
by them from its first step. The FMU runs in the master's Python interpreter, which needs
pythonfmu installed.

To swap in another controller, write a class like this one with the same outputs (or more of the
plant's inputs: `actuation_mode`, `muscle_force[i]`) and point the SSP file's component
`controller` at its FMU.
"""

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real

PARAMETERS = {
    "f0": ("N", 0.5),
    "k": ("rad/m", 6.283185307179586),
    "omega": ("rad/s", 74.3436511385474),
    "phase": ("rad", 0.0),
}


class WaveController(Fmi2Slave):
    author = "soft-crawler"
    description = "Open-loop travelling wave for the crawler plant FMU"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        for name, (unit, start) in PARAMETERS.items():
            setattr(self, name, start)
            self.register_variable(
                Real(
                    name,
                    causality=Fmi2Causality.parameter,
                    variability=Fmi2Variability.tunable,
                    description=f"wave {name}, {unit}",
                )
            )
            self.register_variable(
                Real(
                    f"wave_{name}",
                    causality=Fmi2Causality.output,
                    variability=Fmi2Variability.discrete,
                    description=f"wave {name} for the plant, {unit}",
                    getter=lambda name=name: getattr(self, name),
                )
            )

    def do_step(self, current_time, step_size):
        return True
