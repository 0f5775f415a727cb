"""Names and integer codes shared by the command line, the config and the kernels.

A module without imports, so that the command line can offer the choices (``--body``) without
loading numpy or numba (``sins navigate --help`` starts in ~0.1 s).
"""

FLU, RFU, FRD = 0, 1, 2                  # body axes (docs/formats.md): forward-left-up, right-forward-up, forward-right-down
BODY_CONVENTIONS = {"flu": FLU, "rfu": RFU, "frd": FRD}

# the platforms of --vehicle / fusion.vehicle (their constraints: sinscli.fusion.options.VEHICLE_PRESETS)
VEHICLES = ("none", "car", "robot", "pedestrian", "aircraft")
