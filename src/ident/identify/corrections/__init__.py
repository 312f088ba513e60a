"""The corrections room of ident.identify."""
