import pytest

from bowden.errors import AccessDeniedError, ParameterError
from bowden.web.security import SessionToken, same_origin


def test_fresh_tokens_are_long_and_different():
    a, b = SessionToken(), SessionToken()
    assert len(a.value) >= 40 and a.value != b.value
    assert a.value not in repr(a)


def test_matching():
    token = SessionToken("0123456789abcdefXYZ")
    assert token.matches("0123456789abcdefXYZ")
    for wrong in ("0123456789abcdefXYz", "0123456789abcdefXY", "", None, 123, "0123456789abcdefXYZ "):
        assert not token.matches(wrong)


def test_require_says_whether_a_token_was_missing_or_wrong():
    token = SessionToken("0123456789abcdefXYZ")
    token.require([None, "0123456789abcdefXYZ"])
    with pytest.raises(AccessDeniedError, match="needs the session token"):
        token.require([None, ""])
    with pytest.raises(AccessDeniedError, match="wrong session token") as refusal:
        token.require(["guess-guess-guess-guess"])
    assert "guess" not in str(refusal.value)


def test_short_tokens_are_refused():
    with pytest.raises(ParameterError):
        SessionToken("short")
    with pytest.raises(ParameterError):
        SessionToken("with a space in it here")


def test_same_origin_websocket_handshakes():
    assert same_origin({"host": "127.0.0.1:8765", "origin": "http://127.0.0.1:8765"})
    assert same_origin({"host": "127.0.0.1:8765"})  # not a browser
    assert not same_origin({"host": "127.0.0.1:8765", "origin": "http://evil.example"})
    assert not same_origin({"host": "127.0.0.1:8765", "origin": "http://127.0.0.1:9999"})
    assert not same_origin({"host": "127.0.0.1:8765", "origin": "null"})
