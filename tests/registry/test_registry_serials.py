"""ANSI/CTA-2063-A serials and the other F3411 ID types."""

import pytest

from registry.serials import SerialError, validate_cta2063, validate_uas_id


@pytest.mark.parametrize("serial", ["1581F5FJD12345678901", "MFGA1X", "ABCD9123456789", "0000F" + "Z" * 15])
def test_valid_serials(serial):
    assert validate_cta2063(serial) == serial


@pytest.mark.parametrize("serial, match", [
    ("1581F5FJD123456789", "announces 15 characters .* found 13"),
    ("1581G5FJD12345678901", "length character 'G'"),
    ("1581O5FJD1234567890", "not allowed"),
    ("MFGI1A", "not allowed"),
    ("1581-5FJD", "not allowed"),
    ("MFG", "too short"),
    ("MFGA0", "too short"),
    ("MFGA0X", "length character '0'"),
])
def test_invalid_serials(serial, match):
    with pytest.raises(SerialError, match=match):
        validate_cta2063(serial)


def test_lower_case_is_normalised():
    assert validate_cta2063(" 1581f5fjd12345678901 ") == "1581F5FJD12345678901"


def test_other_id_types():
    assert validate_uas_id("fa3abc1234", "caa_registration") == "FA3ABC1234"
    assert validate_uas_id("FIN-87.X", "caa_registration") == "FIN-87.X"
    u = "123e4567-e89b-12d3-a456-426614174000"
    assert validate_uas_id(u.upper(), "utm_uuid") == u
    assert validate_uas_id("0xE1deadbeef", "specific_session") == "E1DEADBEEF"
    for value, id_type in [("", "caa_registration"), ("has space", "caa_registration"),
                           ("X" * 21, "caa_registration"), ("not-a-uuid", "utm_uuid"),
                           ("00ABCD", "specific_session"), ("E1D", "specific_session"),
                           ("AB" * 21, "specific_session"), ("X", "imei")]:
        with pytest.raises(SerialError):
            validate_uas_id(value, id_type)
