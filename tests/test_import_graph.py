"""No import cycle among our modules, deferred imports included (tests/import_graph.py draws
the graph: `python -m tests.import_graph`)."""

from __future__ import annotations

from pathlib import Path

from tests import import_graph


def test_no_import_cycle_even_through_imports_inside_functions() -> None:
    graph = import_graph.build()
    assert len(graph) > 100 and sum(map(len, graph.values())) > 500
    found = import_graph.cycles(graph)
    assert not found, "import cycles:\n" + "\n".join(" -> ".join(c) for c in found)


def test_a_cycle_closed_inside_a_function_is_found_and_named(tmp_path: Path) -> None:
    pkg = tmp_path / "pkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "a.py").write_text("from pkg import b\n")
    (pkg / "b.py").write_text("def f():\n    from . import c\n")
    (pkg / "c.py").write_text("def g():\n    import pkg.a\n")
    (pkg / "d.py").write_text("import pkg.a\n")
    graph = import_graph.build(tmp_path, ("pkg",))
    assert graph["pkg.b"] == {"pkg", "pkg.c"}
    assert import_graph.cycles(graph) == [["pkg.a", "pkg.b", "pkg.c", "pkg.a"]]


def test_the_command_prints_the_graph_and_its_cycles(capsys) -> None:
    assert import_graph.main([]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert any(line.startswith("signatures.dsp.torch_cube: ") and "signatures.dsp.cube_scale" in line for line in lines)
    assert import_graph.main(["--cycles"]) == 0
    assert capsys.readouterr().out.startswith("no cycle among ")
    assert import_graph.main(["--dot"]) == 0
    assert '"authn.check" -> "core.errors";' in capsys.readouterr().out


def test_an_import_only_a_type_checker_reads_closes_no_cycle(tmp_path: Path) -> None:
    pkg = tmp_path / "pkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "a.py").write_text("from pkg import b\n")
    (pkg / "b.py").write_text("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from pkg import a\n"
                              "else:\n    import pkg.c\n")
    (pkg / "c.py").write_text("import typing\nif typing.TYPE_CHECKING:\n    import pkg.b\n")
    graph = import_graph.build(tmp_path, ("pkg",))
    assert graph["pkg.b"] == {"pkg.c"}  # the else branch runs
    assert graph["pkg.c"] == set()
    assert import_graph.cycles(graph) == []
