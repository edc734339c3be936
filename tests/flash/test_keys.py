"""Site keys read one way everywhere, and per-driver keys derived from them (docs/protocol.md)."""

from __future__ import annotations

import hashlib
import hmac

import pytest

from planner.cli.common import site_key
from planner.errors import UsageError
from planner.flash.keys import driver_key, journal_key, plan_key, site_key_from
from planner.flash.sim.protocol_sim import SimUrlError, bus_from_url

KEY = bytes(range(32))


def test_a_key_is_hex_with_any_whitespace_or_in_a_file_raw_bytes():
    assert site_key_from(b"0001 0203\n0405060708090a0b0c0d0e0f101112131415161718191a1b1c1d1e1f\n") == KEY
    assert site_key_from(KEY) == KEY  # raw bytes in a key file
    with pytest.raises(ValueError, match="has 2 bytes; it must have 16 to 64 \\(hex or raw\\)"):
        site_key_from(b"abcd")
    with pytest.raises(ValueError, match="must be hex digits"):
        site_key_from(KEY.hex()[:-1].encode(), raw=False)  # an odd count is not raw bytes in disguise


def test_the_environment_and_sim_urls_take_hex_only(monkeypatch):
    monkeypatch.setenv("VLP_SITE_KEY", KEY.hex())
    assert site_key(None) == KEY
    monkeypatch.setenv("VLP_SITE_KEY", KEY.hex()[:-1])
    with pytest.raises(UsageError, match="VLP_SITE_KEY: the site key must be hex digits"):
        site_key(None)
    monkeypatch.setenv("VLP_SITE_KEY", "ab" * 8 + "zz" * 8)
    with pytest.raises(UsageError, match="must be hex digits"):
        site_key(None)
    with pytest.raises(SimUrlError, match="sim:// URL: key: the site key has 2 bytes; it must have 16 to 64 "
                                          "\\(32 to 128 hex digits\\)"):
        bus_from_url("sim://?key=abcd")


def test_each_driver_has_its_own_key_derived_from_the_site_key():
    a, b = driver_key(KEY, "SIM-000001"), driver_key(KEY, "SIM-000002")
    assert a == hmac.new(KEY, b"VLP driver key v1\x00SIM-000001", hashlib.sha256).digest() and a != b
    assert a.hex().startswith("6eab083b")  # the worked example of docs/protocol.md
    with pytest.raises(ValueError):
        driver_key(KEY, "")


def test_the_plan_and_journal_keys_are_derived_under_their_own_labels():
    assert plan_key(KEY) == hmac.new(KEY, b"VLP plan key v1\x00", hashlib.sha256).digest()
    assert plan_key(KEY).hex().startswith("fb093b91")  # the worked example of docs/plan-format.md
    assert journal_key(KEY) == hmac.new(KEY, b"VLP journal key v1\x00", hashlib.sha256).digest()
    assert len({plan_key(KEY), journal_key(KEY), driver_key(KEY, "SIM-000001")}) == 3


def test_a_key_file_every_user_can_read_is_warned_about():
    import stat
    import tempfile
    import warnings
    from pathlib import Path

    from planner.errors import PlannerWarning

    folder = Path(tempfile.mkdtemp())  # under /tmp, which every user may search
    try:
        folder.chmod(0o755)
        key = folder / "site.key"
        key.write_text(bytes(range(32)).hex())
        key.chmod(0o644)
        with pytest.warns(PlannerWarning) as said:
            assert site_key(key) == bytes(range(32))
        assert [str(w.message) for w in said] == [
            f"--key-file {key} is readable by every user of this machine: chmod 600 {key}"]
        assert bytes(range(32)).hex() not in str(said[0].message)
        for private in ((key, 0o600), (folder, 0o700)):  # the file, or its folder, closed to others: no warning
            key.chmod(0o644)
            folder.chmod(0o755)
            private[0].chmod(private[1])
            with warnings.catch_warnings():
                warnings.simplefilter("error", PlannerWarning)
                assert site_key(key) == bytes(range(32))
        assert not key.stat().st_mode & stat.S_IROTH or not folder.stat().st_mode & stat.S_IXOTH
    finally:
        folder.chmod(0o700)
        for p in folder.iterdir():
            p.unlink()
        folder.rmdir()
