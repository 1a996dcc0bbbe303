"""The FMU's files in the temporary directory are shared, not one set per process: a Dask worker
closed with its cluster (and a killed test worker) runs no exit handler, and a folder of its own
per process was left behind each time (12 per run of the suite, 2026-12-05). The shipped FMU is
one file per digest and its extraction one folder per FMU file, both written beside their place
and renamed into it."""

from __future__ import annotations

import tempfile

from tether import campaign, fmu
from tether.fmu import fmu_path


def test_the_shipped_fmu_is_one_file_per_digest_written_whole(tmp_path, monkeypatch):
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    data = fmu_path().read_bytes()
    first = campaign._shipped_file("ab" * 32, data)
    again = campaign._shipped_file("ab" * 32, data)
    assert first == again and first.read_bytes() == data
    assert sorted(p.name for p in tmp_path.iterdir()) == [first.name]        # no part file left


def test_the_fmu_is_extracted_once_per_file_into_a_shared_folder(tmp_path, monkeypatch):
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    path = fmu_path()
    key = fmu._key(path)
    first = fmu._shared_extraction(path, key)
    again = fmu._shared_extraction(path, key)          # a second process: the folder is there
    assert first == again and (first / "modelDescription.xml").is_file()
    assert [p.name for p in tmp_path.iterdir()] == [first.name]             # no part folder left
