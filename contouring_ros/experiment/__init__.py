"""An experiment by concept, one module each:

- :mod:`.scenarios`: the config/ directory, the scenario names and the part programs found there,
- :mod:`.schema`: :class:`~.schema.Param`, the limits, the ranges the catalogue shares, the checks of a value,
- :mod:`.ros_yaml`: the reader that types a file as the ROS 2 parameter parser does, and safe file reading,
- :mod:`.catalogue`: the built-in types of every role, one module per role,
- :mod:`.model`: the validated :class:`~.model.Experiment`,
- :mod:`.validate`: a file's and one node's parameters checked, in one-line errors,
- :mod:`.build`: the core objects of an Experiment,
- :mod:`.files`: reading an experiment file, the text a bag keeps, the namespaced file,
- :mod:`.settings`: a file's settings by grid key (``ccc.kp``, ``curve.h``), as sweeps and ``--set`` name them,
- :mod:`.registry`: one registry per role (type name -> class, parameters, constraints; plugins alike),
- :mod:`.guard`: the guard a plugin's object runs under.

:mod:`contouring_ros.config` re-exports their public names for code written before this package. Nothing
is imported here: ``contouring_ros.experiment.scenarios`` loads without numpy or YAML."""
