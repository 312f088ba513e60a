"""The estimation room of ident.identify."""
