"""Closed-form contact forces the simulation is checked against (and the fit's examples use)."""
import math


def hertz_sphere(radius, depth, youngs_modulus, poissons_ratio):
    """Force (N) of a rigid frictionless sphere of radius R pressed to depth d into an elastic
    half-space (Hertz): 4/3 E/(1 - nu^2) sqrt(R) d^1.5."""
    if depth <= 0.0:
        return 0.0
    nu = poissons_ratio
    return 4.0 / 3.0 * youngs_modulus / (1.0 - nu * nu) * math.sqrt(radius) * depth ** 1.5


def hertz_on_bonded_layer(radius, depth, thickness, youngs_modulus, poissons_ratio):
    """The same sphere pressed into a layer of thickness t bonded to a rigid base: Hertz's force
    times the series of Dimitriadis et al. 2002 (Biophys. J. 82, eq. 12) in chi = sqrt(R d) / t."""
    if depth <= 0.0:
        return 0.0
    nu = poissons_ratio
    a0 = -(1.2876 - 1.4678 * nu + 1.3442 * nu * nu) / (1.0 - nu)
    b0 = (0.6387 - 1.0277 * nu + 1.5164 * nu * nu) / (1.0 - nu)
    chi = math.sqrt(radius * depth) / thickness
    pi = math.pi
    series = (1.0 - 2.0 * a0 / pi * chi + 4.0 * a0 * a0 / pi ** 2 * chi ** 2
              - 8.0 / pi ** 3 * (a0 ** 3 + 4.0 * pi ** 2 / 15.0 * b0) * chi ** 3
              - 16.0 * a0 / pi ** 4 * (a0 ** 3 + 3.0 * pi ** 2 / 5.0 * b0) * chi ** 4)
    return hertz_sphere(radius, depth, youngs_modulus, nu) * series
