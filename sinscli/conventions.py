"""Names and integer codes shared by the command line, the config and the kernels.

A module without imports, so that the command line can offer the choices (``--body``) without
loading numpy or numba (``sins navigate --help`` starts in ~0.1 s).
"""

FLU, RFU, FRD = 0, 1, 2                  # body axes (docs/formats.md): forward-left-up, right-forward-up, forward-right-down
BODY_CONVENTIONS = {"flu": FLU, "rfu": RFU, "frd": FRD}

# the platforms of --vehicle / fusion.vehicle (their constraints: sinscli.fusion.options.VEHICLE_PRESETS)
VEHICLES = ("none", "car", "robot", "pedestrian", "aircraft")

# the choices of the config's keys and of the command line's options alike (sinscli.config.SCHEMA, click.Choice)
BODY_NAMES = tuple(BODY_CONVENTIONS)                         # imu.body, --body
ATTITUDES = ("dcm", "quat", "krylov", "euler")               # navigation.attitude, --attitude
DCM_VARIANTS = ("exact", "seed000")                          # navigation.dcm_variant, --dcm-variant
CONING_ORDERS = (1, 2, 3, 4)                                 # navigation.coning, --coning
NAV_FRAMES = ("enu", "launch-inertial")                      # navigation.frame, --frame
EULER_INTEGRATORS = ("euler", "rk4")                         # navigation.euler_integrator, --euler-integrator
ON_SINGULARITY = ("continue", "stop")                        # navigation.on_singularity, --on-singularity
ROS_TIMES = ("header", "log")                                # ros.time, sins convert --time
ODOMETRY_FRAMES = ("auto", "body", "vehicle", "sensor")      # odometry.frame
TIME_SYSTEMS = ("utc", "gps")          # imu.time_system: UTC-based UNIX time, or GPS time read as POSIX seconds
ALIGN_METHODS = ("static", "inertial", "gnss-inertial", "kf")    # align.method, --method, --align
ALIGN_EPOCHS = ("end", "start")                              # align.epoch, --epoch
FUSION_STATES = (15, 21)                                     # fusion.states
BIAS_MODELS = ("gm-noise", "gm-decay")                       # fusion.bias_model
ESTIMABLE = ("lever_arm", "time_offset")                     # fusion.estimate
