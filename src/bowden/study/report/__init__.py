"""The study report: the HTML document, its sections, figures and tables (the paper's layout), and the
sections of a lab's own protocols."""
