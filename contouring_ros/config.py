"""Experiment files: a thin re-export of :mod:`contouring_ros.experiment`, for code written against the
names this module held before that package (plugins import :class:`Param` from here).

Where each concept lives now:

- :mod:`contouring_ros.experiment.schema`: :class:`Param`, the limits, the shared ranges, the value checks,
- :mod:`contouring_ros.experiment.ros_yaml`: the reader that types a file as the ROS 2 parameter parser does,
- :mod:`contouring_ros.experiment.catalogue`: every built-in type of every role (one module per role),
- :mod:`contouring_ros.experiment.model`: :class:`Experiment`,
- :mod:`contouring_ros.experiment.validate`: validation of a file and of one node's parameters,
- :mod:`contouring_ros.experiment.build`: the core objects of an experiment,
- :mod:`contouring_ros.experiment.files`: reading a file, the text a bag keeps, the namespaced file.
"""
from __future__ import annotations

from .experiment.build import (  # noqa: F401
    build_clock, build_controller, build_curve, build_curve_from, build_disturbance, build_estimator, build_loop,
    build_plant, build_schedule, build_schedule_from, build_servo, in_position_windows, initial_state)
from .experiment.catalogue import (  # noqa: F401
    CONTROLLERS, CURVES, DISTURBANCES, ESTIMATORS, GLOBALS, OPTIONAL_NODES, PLANTS, ROLE_TYPES, ROLES, SCHEDULES,
    SERVOS)
from .experiment.catalogue.controllers import APPROXIMATIONS, WHOLE_COMMAND_CONTROLLERS  # noqa: F401
from .experiment.catalogue.curves import TOOL_PATH_TYPES, WINDOW, program_warnings  # noqa: F401
from .experiment.catalogue.estimators import branch_check_settings  # noqa: F401
from .experiment.catalogue.plants import DISTURBANCE_UNITS  # noqa: F401
from .experiment.catalogue.servos import plan_correction  # noqa: F401
from .experiment.catalogue.shared import (  # noqa: F401
    INITIAL_STATES, INVALID_INPUT_POLICIES, LAYOUTS, OVERRUN_POLICIES, TIMINGS)
from .experiment.files import load_experiment, namespaced_parameter_file, recorded_text  # noqa: F401
from .experiment.model import Experiment  # noqa: F401
from .experiment.ros_yaml import _ros_scalar, read_yaml  # noqa: F401
from .experiment.schema import (  # noqa: F401
    DEFAULT_BOUNDS, GLOBAL_SECTION, LIMIT, MAX_DEPTH, MAX_DURATION, MAX_EVENTS, MAX_FILE_BYTES, MAX_ITEMS,
    MAX_PROGRAM_BYTES, MAX_STEPS, MAX_TEXT, NUMERIC_KINDS, RENAMED_KEYS, REQUIRED, ROS_PARAMETERS, Param, _typed)
from .experiment.validate import (  # noqa: F401
    RESERVED_AXIS_NAMES, ROS_BUILTIN_PARAMETERS, _AXIS_NAME, _check_entry, check_ccc_takes_state, is_axis_name,
    controller_uses_state, experiment_for_node, experiment_from_data, node_sections, parse_experiment,
    section_from_parameters, split_groups, validate_section)
from .notices import note_while_slow  # noqa: F401

__all__ = ["Experiment", "load_experiment", "parse_experiment", "read_yaml", "experiment_from_data", "build_loop",
           "build_curve", "build_schedule", "build_plant", "build_servo", "build_estimator", "build_controller",
           "initial_state", "controller_uses_state", "check_ccc_takes_state", "GLOBAL_SECTION", "node_sections",
           "section_from_parameters", "experiment_for_node", "namespaced_parameter_file"]
