"""The friction room of ident.identify."""
