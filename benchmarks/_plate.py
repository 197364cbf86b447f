"""The free square steel plate of the shell benchmarks (shell_plate*.py): its material, Leissa's
frequency parameters and lambda = omega a^2 sqrt(rho h / D), D = E h^3 / (12 (1 - nu^2))."""
import numpy as np

from ffrf_fmu.solid.mesh import Material

STEEL = Material(E=210e9, nu=0.3, rho=7800.0)
LEISSA = [13.49, 19.79, 24.43, 35.02, 35.02]  # Leissa 1969 (after Barton), elastic modes 1-5


def rigidity(h: float, mat: Material = STEEL) -> float:
    """The plate's bending stiffness D [N m]."""
    return mat.E * h**3 / (12 * (1 - mat.nu**2))


def frequency_parameter(omega, h: float, a: float = 1.0, mat: Material = STEEL):
    """lambda = omega a^2 sqrt(rho h / D) of circular frequencies omega [rad/s]."""
    return np.asarray(omega) * a**2 * np.sqrt(mat.rho * h / rigidity(h, mat))


def elastic_lambdas(fe, h: float, modes: int, a: float = 1.0, mat: Material = STEEL):
    """lambda of the free plate's first `modes` elastic modes (its 6 rigid ones skipped; shift-invert
    about -1e-2 D / (rho h a^4), below the first elastic frequency)."""
    from ffrf_fmu.solid.shell import free_modes

    w2, _ = free_modes(fe, 6 + modes, shift=-1e-2 * rigidity(h, mat) / (mat.rho * h * a**4))
    return frequency_parameter(np.sqrt(np.abs(w2[6:])), h, a, mat)


def header(modes: int) -> str:
    return "lambda = omega a^2 sqrt(rho h / D), elastic modes 1..%d; Leissa: %s" % (modes, LEISSA)
