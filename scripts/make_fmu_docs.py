#!/usr/bin/env python3
"""documentation/index.html of KevlarTether.fmu, generated from modelDescription.xml.

    python3 scripts/make_fmu_docs.py modelDescription.xml out.html

scripts/package_fmu.py imports render() to put the page into the FMU.
"""
import html
import re
import sys
import xml.etree.ElementTree as ET

CSS = """
body { font-family: sans-serif; max-width: 70em; margin: 2em auto; padding: 0 1em; color: #222; }
h1 { margin-bottom: 0.2em; } .sub { color: #555; margin-top: 0; }
table { border-collapse: collapse; width: 100%; margin: 1em 0; font-size: 0.92em; }
th, td { border: 1px solid #ccc; padding: 0.25em 0.5em; text-align: left; vertical-align: top; }
th { background: #eee; } tr:nth-child(even) td { background: #fafafa; }
code { background: #f3f3f3; padding: 0 0.2em; } .num { text-align: right; white-space: nowrap; }
"""


def e(x):
    return html.escape("" if x is None else str(x))


def type_elem(sv):
    for child in sv:
        if child.tag in ("Real", "Integer", "Boolean", "String", "Enumeration"):
            return child
    return None


# an Integer switch's description lists its values: "1 = element (what it is), 2 = payload (...)"
SWITCH_VALUE = re.compile(r"\b(\d+) = ([a-z_]+)\b")


def switch_values(description):
    """[(value, name, what it is)] listed in a switch's description (the parenthesis after each name)."""
    out = []
    for m in SWITCH_VALUE.finditer(description or ""):
        rest, what = description[m.end():], ""
        if rest.startswith(" ("):
            depth = 0
            for i, ch in enumerate(rest[1:], 1):
                depth += {"(": 1, ")": -1}.get(ch, 0)
                if depth == 0:
                    what = rest[2:i]
                    break
        out.append((m.group(1), m.group(2), what))
    return out


def render(root, extra=None):
    """root: the parsed <fmiModelDescription> element. extra: {'sundials_version', 'source_files'}."""
    extra = extra or {}
    a = root.attrib
    name = a.get("modelName", "FMU")
    enums = {}   # switch variable -> [(value, name, description)]
    for sv in root.iter("ScalarVariable"):
        t = type_elem(sv)
        if t is not None and t.tag == "Integer" and switch_values(sv.get("description")):
            enums[sv.get("name")] = switch_values(sv.get("description"))

    out = []
    w = out.append
    w("<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n")
    w("<title>%s %s</title>\n<style>%s</style>\n</head>\n<body>\n" % (e(name), e(a.get("version")), CSS))
    w("<h1>%s</h1>\n<p class=\"sub\">FMI %s &middot; version %s &middot; GUID <code>%s</code></p>\n"
      % (e(name), e(a.get("fmiVersion")), e(a.get("version")), e(a.get("guid"))))
    w("<p>%s.</p>\n" % e((a.get("description") or "").rstrip(".")))

    kinds = []
    me, cs = root.find("ModelExchange"), root.find("CoSimulation")
    if me is not None:
        kinds.append("Model Exchange")
    if cs is not None:
        kinds.append("Co-Simulation (CVODE inside, variable communication step size)")
    w("<h2>What the unit is</h2>\n<ul>\n")
    w("<li>Interfaces: %s, one binary <code>binaries/linux64/%s.so</code>.</li>\n"
      % (e(", ".join(kinds)), e((cs if cs is not None else me).get("modelIdentifier"))))
    n_states = len(root.findall("ModelStructure/Derivatives/Unknown"))
    w("<li>%d continuous states, %s event indicators.</li>\n" % (n_states, e(a.get("numberOfEventIndicators", "0"))))
    caps = []
    for key in ("canGetAndSetFMUstate", "canSerializeFMUstate"):
        if (cs is not None and cs.get(key) == "true") or (me is not None and me.get(key) == "true"):
            caps.append(key)
    if caps:
        w("<li>Capabilities: %s.</li>\n" % e(", ".join(caps)))
    if extra.get("sundials_version"):
        w("<li>Integrator: CVODE from SUNDIALS %s (BSD-3-Clause), compiled in.</li>\n" % e(extra["sundials_version"]))
    if extra.get("source_files"):
        w("<li>Sources: <code>sources/</code> holds all C code (%d files listed in <code>&lt;SourceFiles&gt;</code>); "
          "rebuild with e.g. <code>fmpy compile KevlarTether.fmu</code> (include directory: <code>sources/</code> only, "
          "no defines).</li>\n" % len(extra["source_files"]))
    de = root.find("DefaultExperiment")
    if de is not None:
        w("<li>Default experiment: %s.</li>\n" % e(", ".join("%s=%s" % kv for kv in de.attrib.items())))
    w("</ul>\n")

    if "rig" in enums:
        w("<h2>Rigs</h2>\n<p>Parameter <code>rig</code> selects the test rig:</p>\n<table>\n"
          "<tr><th>value</th><th>rig</th><th>description</th></tr>\n")
        for v, n, d in enums["rig"]:
            w("<tr><td class=\"num\">%s</td><td><code>%s</code></td><td>%s</td></tr>\n" % (e(v), e(n), e(d)))
        w("</table>\n")

    others = [k for k in enums if k != "rig"]
    if others:
        w("<h2>Model switches</h2>\n<table>\n<tr><th>parameter</th><th>value</th><th>name</th><th>description</th></tr>\n")
        for k in others:
            for v, n, d in enums[k]:
                w("<tr><td>%s</td><td class=\"num\">%s</td><td><code>%s</code></td><td>%s</td></tr>\n"
                  % (e(k), e(v), e(n), e(d)))
        w("</table>\n")

    w("<h2>Variables</h2>\n<table>\n<tr><th>#</th><th>name</th><th>vr</th><th>causality</th><th>variability</th>"
      "<th>type</th><th>unit</th><th>start</th><th>min</th><th>max</th><th>description</th></tr>\n")
    mv = root.find("ModelVariables")
    for i, sv in enumerate(mv.findall("ScalarVariable") if mv is not None else [], start=1):
        t = type_elem(sv)
        tname = t.tag if t is not None else ""
        if t is not None and t.get("declaredType"):
            tname = "%s (%s)" % (tname, t.get("declaredType"))
        start = t.get("start", "") if t is not None else ""
        if t is not None and sv.get("name") in enums and start:
            for v, n, _ in enums[sv.get("name")]:
                if v == start:
                    start = "%s (%s)" % (n, v)
        if t is not None and t.get("derivative"):
            tname += ", derivative of #%s" % t.get("derivative")
        w("<tr><td class=\"num\">%d</td><td><code>%s</code></td><td class=\"num\">%s</td><td>%s</td><td>%s</td>"
          "<td>%s</td><td>%s</td><td class=\"num\">%s</td><td class=\"num\">%s</td><td class=\"num\">%s</td><td>%s</td></tr>\n"
          % (i, e(sv.get("name")), e(sv.get("valueReference")), e(sv.get("causality", "local")),
             e(sv.get("variability", "continuous")), e(tname), e(t.get("unit", "") if t is not None else ""),
             e(start), e(t.get("min", "") if t is not None else ""), e(t.get("max", "") if t is not None else ""),
             e(sv.get("description", ""))))
    w("</table>\n")
    w("<p class=\"sub\">Generated from modelDescription.xml by scripts/make_fmu_docs.py.</p>\n</body>\n</html>\n")
    return "".join(out)


def main():
    if len(sys.argv) != 3:
        sys.exit("usage: make_fmu_docs.py modelDescription.xml out.html")
    root = ET.parse(sys.argv[1]).getroot()
    with open(sys.argv[2], "w", encoding="utf-8") as f:
        f.write(render(root))


if __name__ == "__main__":
    main()
