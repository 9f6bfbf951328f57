"""Form values remembered per profile: typed text kept as typed, bad files ignored."""

from __future__ import annotations

from pathlib import Path

from spm_console.store.form_memory import MAX_BYTES, FormMemory


def test_round_trip_keeps_the_typed_text_per_profile(tmp_path: Path) -> None:
    m = FormMemory(tmp_path / "c" / "console.json")
    m.put("agile_wrist", "plan.goal", "66.80 155.00 131.48")
    m.put("agile_wrist", "plan.steps", "0150")
    m.put("coaxial", "plan.steps", "90")
    assert m.save() and m.error == ""
    again = FormMemory(tmp_path / "c" / "console.json")
    assert again.get("agile_wrist", "plan.goal") == "66.80 155.00 131.48"
    assert again.get("agile_wrist", "plan.steps") == "0150"  # never reformatted
    assert again.get("coaxial", "plan.steps") == "90"
    assert again.get("coaxial", "plan.goal") is None


def test_bad_files_are_ignored_and_a_failed_save_is_reported(tmp_path: Path) -> None:
    p = tmp_path / "console.json"
    for text in ("not json", "[1, 2]", '{"p": 3}', '{"p": {"k": 5}}', "x" * (MAX_BYTES + 1)):
        p.write_text(text)
        assert FormMemory(p).get("p", "k") is None
    blocked = tmp_path / "file"
    blocked.write_text("")
    m = FormMemory(blocked / "console.json")  # its folder is a file
    m.put("p", "k", "1")
    assert not m.save() and str(blocked) in m.error
