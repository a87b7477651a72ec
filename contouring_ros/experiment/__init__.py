"""An experiment by concept, one module each:

- :mod:`.scenarios`: the config/ directory, the scenario names and the part programs found there,
- :mod:`.schema`: :class:`~.schema.Param`, the limits and bounds of every number, the checks of a value,
- :mod:`.ros_yaml`: the reader that types a file as the ROS 2 parameter parser does, and safe file reading,
- :mod:`.model`: the validated :class:`~.model.Experiment`.

The built-in types of each role, validation and building are in :mod:`contouring_ros.config`, which also
re-exports every public name of these modules, so its imports keep working. Nothing is imported here:
``contouring_ros.experiment.scenarios`` loads without numpy or YAML."""
