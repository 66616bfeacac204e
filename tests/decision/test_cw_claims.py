"""The CW claims bench's parts (lab/bench/cw_claims.py): the site policy is the default less exactly
the forbid a CW radar cannot satisfy, and the bench registry holds the drone from its physics."""

from __future__ import annotations

import pytest

from lab.bench.cw_claims import (CW_DROPPED_FORBID, GENUINE_SERIAL, IMPOSTOR_SERIAL, bench_registry, broadcasting,
                                 cw_site_policy)


def test_the_cw_site_policy_drops_one_forbid_and_validates() -> None:
    from importlib.resources import files

    from authn.policy import PolicyEngine

    default = PolicyEngine.from_text(files("authn.policies").joinpath("default.cedar").read_text())
    site = PolicyEngine.from_text(cw_site_policy(), "cw-site")
    assert f'@id("{CW_DROPPED_FORBID}")' in default.text and f'@id("{CW_DROPPED_FORBID}")' not in site.text
    assert len(site.effects) == len(default.effects) - 1
    assert site.text.count("@id(") == default.text.count("@id(") - 1  # nothing else went with it


def test_the_bench_registry_holds_the_drone_from_its_physics(tmp_path) -> None:
    from lab.accuracy import DJI_QUAD
    from registry.dbapi import transaction
    from registry.store import custom_profiles, get_identity

    db = f"sqlite:///{tmp_path / 'r.sqlite3'}"
    bench_registry(db)
    with transaction(db) as s:
        assert [p.slug for p in custom_profiles(s)] == [DJI_QUAD.slug]
        assert get_identity(s, GENUINE_SERIAL).model == DJI_QUAD.slug
        assert get_identity(s, IMPOSTOR_SERIAL).model == "phantom4"


def test_a_dwell_broadcasts_the_serial_it_is_given() -> None:
    from lab.accuracy import CONDITIONS, render_condition
    from remoteid import BasicId
    from remoteid.codec import decode_rows_raw

    rec, scene, *_ = render_condition(CONDITIONS["cw-hover-tagged"], "training", 0)
    for serial in (GENUINE_SERIAL, IMPOSTOR_SERIAL):
        sent = broadcasting(rec, scene, serial)
        ids = {m.uas_id.strip() for m, _ in decode_rows_raw(sent.remote_id) if isinstance(m, BasicId)}
        assert ids == {serial} and sent.iq is rec.iq


def test_no_dwells_is_refused(capsys, tmp_path) -> None:
    from lab.bench.cw_claims import main

    with pytest.raises(SystemExit) as exc:
        main(["--model", str(tmp_path), "--n", "0"])
    assert exc.value.code == 2 and "--n 0" in capsys.readouterr().err
