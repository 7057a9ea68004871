"""Publishing: rendering solutions (Jinja2 templates, JSON), figures (matplotlib), handouts (PDF, tex, md, html)."""
