"""What the audit modules share and nothing outside authn.audit uses: stored rows read back
(`rows`), signed heads as rows (`headrows`). Names here are public to the package only;
no audit module imports another's underscore name (tests/decision/test_audit_boundaries.py).
"""
