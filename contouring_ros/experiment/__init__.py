"""An experiment by concept, one module each:

- :mod:`.scenarios`: the config/ directory, the scenario names and the part programs found there.

The built-in types of each role, validation and building are in :mod:`contouring_ros.config`. Nothing is
imported here: ``contouring_ros.experiment.scenarios`` loads without numpy or YAML."""
