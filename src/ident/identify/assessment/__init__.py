"""The assessment room of ident.identify."""
