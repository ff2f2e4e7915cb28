"""Published point estimates of the Sharif University of Technology shaking table (SST).

From the hysteresis-loop identification of the reference study: effective mass 13.2 t,
strut stiffness 0.72 MN/m, damping 29.6 kN/(m/s)^0.5 with exponent 0.5, and friction
coefficient 1.27 % of the normal force (hold-down force plus deck weight), about 12.5 kN.
"""

PUBLISHED_SST = {
    "Me": 13_200.0,
    "Ke": 0.72e6,
    "Ce": 29_600.0,
    "alpha": 0.5,
    "Fmu": 12_500.0,
}

# (scale, unit) for printing; files stay in SI
DISPLAY_UNITS = {
    "Me": (1e-3, "t"),
    "Ke": (1e-3, "kN/m"),
    "Ce": (1e-3, "kN/(m/s)^a"),
    "alpha": (1.0, "-"),
    "Fmu": (1e-3, "kN"),
}
