"""tether demo, the README's main job, end to end on the bundled data.

Independent expectations: every bundled reference trace reproduced by its own generating model
(validate's exit status 0), the Bouc-Wen benchmark's published figure for the true equations
(about 2.3e-7 m on test_multisine), and the discovery record's hidden set, which its JSON keeps and
discovery does not read.
"""

import json
import re
from pathlib import Path

REF = Path(__file__).resolve().parents[1] / "reference_results"


def test_demo_validates_reproduces_the_benchmark_and_names_the_hidden_set(tmp_path, run_cli):
    report = tmp_path / "demo"
    status, out, err = run_cli("demo", "--report", report)
    assert status == 0, err
    assert (report / "index.html").is_file()
    assert (report / "validate" / "validation.json").is_file()
    rms = [float(x) for x in re.findall(r"test_multisine\D*?RMS error ([0-9.eE+-]+) m", out)]
    assert rms and rms[0] < 1e-6, out
    hidden = json.loads((REF / "discovery" / "freevib_hidden.json").read_text())
    truth = set(hidden["hidden"]["effects"])
    named = re.search(r"^discovered: ([a-z_, ]+);", out, re.M)
    assert truth and named, out
    assert {e.strip() for e in named.group(1).split(",")} == truth
