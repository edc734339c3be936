"""The site report and the plan's map: content, figures, HTML and PDF files."""
