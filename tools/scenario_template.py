"""The part every scenario file shares: the /** section with the experiment's identity, the paper's numbers
it is compared with, and the shared keys. Used by the tools/make_paper00N_configs.py generators."""


def shared_section(name: str, title: str, paper: dict, axes: list, curve: str, schedule: str) -> str:
    """The YAML text of the /** section. ``paper`` maps source / mce_um / tace_um / rms_um to values
    (strings are quoted); ``curve`` and ``schedule`` are YAML flow mappings."""
    lines = ["/**:", "  ros__parameters:", "    experiment:", f"      name: {name}",
             f'      description: "{title}"', "    paper:"]
    lines += [f'      {key}: "{value}"' if isinstance(value, str) else f"      {key}: {value}"
              for key, value in paper.items()]
    quoted = ", ".join(f'"{axis}"' for axis in axes)
    lines += ["    sample_time: 0.001",
              f"    axes: [{quoted}]  # quoted: the ROS parameter parser reads a bare y as a boolean",
              f"    curve: {curve}", f"    schedule: {schedule}", "    initial_state: on_reference", ""]
    return "\n".join(lines)
