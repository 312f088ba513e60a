"""The model_files room of ident.identify."""
