"""The paper's two protocols, shipped as protocol files."""
