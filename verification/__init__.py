"""Cross-backend verification suite (import name ``cfm_verification``)."""
