"""The visual 3D compass: full 3D rotation between a current view and a snapshot."""
