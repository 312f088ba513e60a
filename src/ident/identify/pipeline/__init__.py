"""The pipeline room of ident.identify."""
