"""The part every scenario file shares: the /** section with the experiment's identity, the paper's numbers
it is compared with, and the shared keys; the header line of a mechanism scenario that says what it adds
beyond the paper. Used by the tools/make_paper00N_configs.py generators."""
from pathlib import Path

import yaml

CLAIMS_DIR = Path(__file__).resolve().parent.parent / "config" / "claims"


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


def with_adds(name: str, text: str) -> str:
    """``text`` with, after its first line, "# Adds beyond the paper: ..." from the ``adds`` of the claim whose
    mechanism pair names the scenario (config/claims/paper<N>.yaml, tests/analysis/test_claims.py asks for the line);
    unchanged for a scenario no mechanism pair names."""
    path = CLAIMS_DIR / f"paper{name[5:8]}.yaml"
    claims = yaml.safe_load(path.read_text())["claims"] if path.exists() else []
    for claim in claims:
        mechanism = claim.get("mechanism") or {}
        if name in (mechanism.get("proposed"), mechanism.get("baseline")):
            first, rest = text.split("\n", 1)
            return f"{first}\n# Adds beyond the paper: {claim['adds']}.\n{rest}"
    return text
