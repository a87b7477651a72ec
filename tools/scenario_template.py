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


def derived_scenario(base_text: str, stem: str, title: str, header: str, sections: dict) -> str:
    """A scenario file of the same scenario as ``base_text`` (a generated file: its /** section, plants and
    every node not in ``sections`` copied as they are) with the node ``sections`` replaced (node -> YAML text
    of its ros__parameters, a flow mapping or an indented block), named ``stem``, described by ``title``,
    under the comment ``header``; its ``paper`` block keeps only the source, marked as not the paper's
    method (the paper's figures are not this method's)."""
    blocks, order, current = {}, [], None
    for line in base_text.splitlines():
        if line and not line[0].isspace() and not line.startswith("#") and line.rstrip().endswith(":"):
            current = line.rstrip()[:-1]
            order.append(current)
            blocks[current] = []
        if current is not None:
            blocks[current].append(line)
    shared, keep = [], True
    for line in blocks["/**"]:
        if line.startswith("      name: "):
            line = f"      name: {stem}"
        elif line.startswith("      description: "):
            line = f'      description: "{title}"'
        elif line.startswith("      source: "):
            line = line[:-1] + ', reference method (not in the paper)"'
        if line.startswith("    paper:"):
            keep = "source"
        elif keep == "source" and line.startswith("      ") and not line.startswith("      source: "):
            continue
        elif not line.startswith("      "):
            keep = True
        shared.append(line)
    blocks["/**"] = shared
    for node, body in sections.items():
        body = body.strip("\n")
        blocks[node] = [f"{node}:", f"  ros__parameters: {body}" if body.startswith("{") else
                        "  ros__parameters:\n" + "\n".join(f"    {line}" for line in body.splitlines()), ""]
    return header + "\n" + "\n".join("\n".join(blocks[node]).rstrip("\n") + "\n" for node in order)


REFERENCE_HEADER = """\
# Paper {paper}, reference method (not in the paper): {title}.
# The scenario of {base}.yaml (its curve, schedule, plants and load, copied), driven by one of the methods
# the contouring literature compares against (docs/REFERENCES.md), so that the benchmark
# (contouring-ros benchmark) ranks it on this scenario beside the paper's methods:
{what}
"""

#: what each reference method's file says of itself (REFERENCE_HEADER's ``what``)
REFERENCE_WHAT = {
    "zpetc": """\
# - ZPETC (Tomizuka, 1987): each axis a PID closed around the zero phase error tracking feedforward of its
#   own sampled loop, designed from the axis model below, reading the reference ahead; no cross-coupling.
#   The PID is the paper's own where the paper has one on these axes ({pid}). The benchmark gives the
#   feedforward's model the realistic machine's computation delay (command_delay) and pairs it with no CCC
#   and with the paper's proposed CCC.""",
    "ilc": """\
# - Cross-coupled ILC (Barton & Alleyne, 2008; Bristow, Tharayil & Alleyne, 2006): the path is run `passes`
#   times; each pass plays back the correction learned from the one before (the contour error vector of the
#   estimate, `lead` steps ahead, times gamma_contour, low-passed at q_cutoff without phase), on the paper's
#   own servos. The benchmark tunes gamma_tracking and gamma_contour and scores the last pass.""",
    "mpcc": """\
# - MPCC (Lam, Manzie & Good, 2013): every axis' whole command from a QP over `horizon` steps of the
#   reference preview, trading contour error, lag and the command's rate within the command limits, on the
#   axis model the paper's own controller uses; the benchmark tunes q_contour, q_lag and r_rate and gives
#   the model the realistic machine's delay and actuator limits.""",
}


def write_reference_methods(out, paper: str, methods: list) -> None:
    """Write each reference-method scenario of ``methods`` [(base stem, stem, method, title, sections, pid)]
    into ``out`` from its base file there (:func:`derived_scenario`)."""
    out = Path(out)
    for base, stem, method, title, sections, pid in methods:
        header = REFERENCE_HEADER.format(paper=paper, title=title, base=base,
                                         what=REFERENCE_WHAT[method].format(pid=pid))
        text = derived_scenario((out / f"{base}.yaml").read_text(), stem, title, header, sections)
        (out / f"{stem}.yaml").write_text(text)
        print(out / f"{stem}.yaml")
