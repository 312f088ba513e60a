"""The payload room of ident.identify."""
